//! Writes the grasp preview (RGB and depth with rectangles) of one procedural object.
//!
//! `cargo run --release -p lgdm-pointcloud --example grasp_preview -- <category> <instance> <image> <out.png>`

use lgdm_pointcloud::grasp::{GraspSpec, grasp_scene};
use lgdm_pointcloud::objects::{ObjectModel, procedural_object};
use lgdm_pointcloud::preview::grasp_preview;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let category = args.get(1).map_or("mug", String::as_str);
    let instance: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(0);
    let image: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(0);
    let out = args.get(4).map_or("grasp_preview.png", String::as_str);
    let mesh = match procedural_object(category, instance, 0) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(2);
        }
    };
    let object = ObjectModel {
        name: format!("{category}_{:02}", instance + 1),
        category: category.to_string(),
        mesh,
        physics: Default::default(),
        parts: Vec::new(),
    };
    let scene = grasp_scene(&GraspSpec::default(), 0, image, &object);
    if let Err(e) = grasp_preview(&scene, &object.name).write_png(out.as_ref()) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
