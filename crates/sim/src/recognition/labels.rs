//! Category and instance names by id ([`Labels`]).
//!
//! **Labels.** Ids are the dataset's ([`lgdm_pointcloud::dataset::label_ids`]): category id =
//! index of the category name in order of first appearance, instance id = index of the object.
//! A model trained by `lgdm train` brings the names of its run (`metrics.json`); names the
//! teacher introduces later are appended (open-ended: no class count is fixed).

use lgdm_pointcloud::dataset::label_ids;
use lgdm_pointcloud::objects::ObjectModel;
use serde::{Deserialize, Serialize};

/// Category and instance names by id (id = index): the dataset's, extended by the teacher.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Labels {
    /// Category names by id.
    pub categories: Vec<String>,
    /// Instance names by id.
    pub instances: Vec<String>,
}

impl Labels {
    /// The ids a dataset of `objects` gives ([`label_ids`]).
    pub fn of_objects(objects: &[ObjectModel]) -> Self {
        let (categories, _) = label_ids(objects);
        Self {
            categories,
            instances: objects.iter().map(|o| o.name.clone()).collect(),
        }
    }

    fn id(names: &mut Vec<String>, name: &str) -> u32 {
        match names.iter().position(|n| n == name) {
            Some(i) => i as u32,
            None => {
                names.push(name.to_string());
                (names.len() - 1) as u32
            }
        }
    }

    /// The id of category `name`, appended when new.
    pub fn category_id(&mut self, name: &str) -> u32 {
        Self::id(&mut self.categories, name)
    }

    /// The id of instance `name`, appended when new.
    pub fn instance_id(&mut self, name: &str) -> u32 {
        Self::id(&mut self.instances, name)
    }

    /// The name of category `id` (`category_<id>` when it has none).
    pub fn category_name(&self, id: u32) -> String {
        self.categories
            .get(id as usize)
            .cloned()
            .unwrap_or_else(|| format!("category_{id}"))
    }

    /// The name of instance `id` (`instance_<id>` when it has none).
    pub fn instance_name(&self, id: u32) -> String {
        self.instances
            .get(id as usize)
            .cloned()
            .unwrap_or_else(|| format!("instance_{id}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lgdm_pointcloud::objects::procedural_library;
    #[test]
    fn labels_extend_open_endedly() {
        let library = procedural_library(&["can", "mug"], 2, 0).unwrap();
        let mut labels = Labels::of_objects(&library);
        assert_eq!(labels.category_id("mug"), 1);
        assert_eq!(labels.instance_id("mug_02"), 3);
        assert_eq!(labels.category_id("teapot"), 2);
        assert_eq!(labels.category_name(2), "teapot");
        assert_eq!(labels.category_name(7), "category_7");
    }
}
