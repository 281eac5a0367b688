//! Dataset generation: objects → turntable sequences → augmentations → MCAP collections,
//! then grasp-labelled images, previews and the manifest.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::mcap_io::{ChannelLabels, CollectionWriter};
use super::{
    CollectionInfo, DatasetError, DatasetSpec, FORMAT_NAME, FORMAT_VERSION, InstanceInfo,
    MANIFEST_FILE, Manifest, POINT_CLOUD_FRAME_ID, PointCloud, Progress,
};
use crate::augment::{Augmentation, subsample};
use crate::math::{Pose, derive_seed};
use crate::mesh::Mesh;
use crate::objects::{ObjectModel, procedural_library, rest_on_table};
use crate::render::{Camera, RenderItem, render};

/// Seed stream tags (keep stable: they define the dataset bytes).
const TAG_SEQUENCE: u64 = 0x5E0;

/// Label of the object in rendered frames.
pub(crate) const OBJECT_LABEL: u8 = 2;

/// Objects, category names and manifest entries, as [`load_objects`] returns them.
pub type LoadedObjects = (Vec<ObjectModel>, Vec<String>, Vec<InstanceInfo>);

/// The objects a spec describes (procedural or imported), the category names in label order,
/// and the per-instance manifest entries.
pub fn load_objects(spec: &DatasetSpec) -> Result<LoadedObjects, DatasetError> {
    let (objects, sources): (Vec<ObjectModel>, Vec<String>) = match &spec.meshes {
        None => {
            let cats: Vec<&str> = spec.categories.iter().map(String::as_str).collect();
            let objects = procedural_library(&cats, spec.instances_per_category, spec.seed)
                .map_err(|e| DatasetError::InvalidSpec {
                    field: "categories",
                    reason: e.to_string(),
                })?;
            let n = objects.len();
            (objects, vec!["procedural".to_string(); n])
        }
        Some(dir) => {
            let objects = crate::import::load_mesh_library(dir)?;
            let sources = objects
                .iter()
                .map(|o| format!("{}/{}", o.category, o.name))
                .collect();
            (objects, sources)
        }
    };
    let mut categories: Vec<String> = Vec::new();
    for o in &objects {
        if !categories.contains(&o.category) {
            categories.push(o.category.clone());
        }
    }
    let instances = objects
        .iter()
        .zip(sources)
        .map(|(o, source)| InstanceInfo {
            name: o.name.clone(),
            category: categories
                .iter()
                .position(|c| *c == o.category)
                .expect("collected above") as u32,
            source,
        })
        .collect();
    Ok((objects, categories, instances))
}

/// Generates the dataset `spec` describes into `out_dir` (created if needed) and returns its
/// manifest. Collection files are written under temporary names and renamed when complete;
/// the manifest is written last, so a failed run never leaves a half-written collection or a
/// manifest that points at missing data.
pub fn generate(
    spec: &DatasetSpec,
    out_dir: &Path,
    progress: &mut dyn FnMut(Progress),
) -> Result<Manifest, DatasetError> {
    spec.validate()?;
    progress(Progress {
        stage: "objects",
        done: 0,
        total: 1,
    });
    let (objects, categories, instances) = load_objects(spec)?;
    progress(Progress {
        stage: "objects",
        done: 1,
        total: 1,
    });
    let collections_dir = out_dir.join("collections");
    std::fs::create_dir_all(&collections_dir).map_err(|e| DatasetError::io(&collections_dir, e))?;
    let camera = spec.camera.camera();

    // Collections in parallel (one file per worker at a time); progress flows back over a channel.
    let n_coll = spec.collections.len();
    let workers = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .clamp(1, n_coll);
    let next = AtomicUsize::new(0);
    let cancel = AtomicBool::new(false);
    let total_views = spec.views(objects.len());
    let (tx, rx) = mpsc::channel::<u64>();
    let mut results: Vec<Option<Result<u64, DatasetError>>> = (0..n_coll).map(|_| None).collect();
    std::thread::scope(|scope| {
        let handles: Vec<_> = (0..workers)
            .map(|_| {
                let tx = tx.clone();
                let (next, cancel, objects, instances, categories) =
                    (&next, &cancel, &objects, &instances, &categories);
                scope.spawn(move || {
                    let mut done = Vec::new();
                    loop {
                        let c = next.fetch_add(1, Ordering::SeqCst);
                        if c >= n_coll {
                            break;
                        }
                        let r = write_collection(
                            spec, c, objects, instances, categories, &camera, out_dir, cancel, &tx,
                        );
                        if r.is_err() {
                            cancel.store(true, Ordering::SeqCst);
                        }
                        done.push((c, r));
                    }
                    done
                })
            })
            .collect();
        drop(tx);
        let mut views = 0u64;
        for n in rx {
            views += n;
            progress(Progress {
                stage: "views",
                done: views,
                total: total_views,
            });
        }
        for h in handles {
            for (c, r) in h.join().expect("collection worker panicked") {
                results[c] = Some(r);
            }
        }
    });
    // Report the first real error (not a cancellation caused by it).
    let mut sizes = Vec::with_capacity(n_coll);
    let mut first_err = None;
    for r in results {
        match r.expect("every collection was attempted") {
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

    let grasp = crate::cornell::export_grasp_set(spec, &objects, &instances, out_dir, progress)?;
    let previews = if spec.previews {
        crate::preview::write_previews(spec, &objects, out_dir, progress)?
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
    write_json_atomic(&out_dir.join(MANIFEST_FILE), &manifest)?;
    Ok(manifest)
}

/// Writes pretty JSON through a temp file renamed into place.
pub(crate) fn write_json_atomic<T: serde::Serialize>(
    path: &Path,
    value: &T,
) -> Result<(), DatasetError> {
    write_atomic(path, |w| {
        use std::io::Write;
        serde_json::to_writer_pretty(&mut *w, value).map_err(std::io::Error::other)?;
        w.write_all(b"\n")
    })
}

/// Relative path of collection `index`'s file.
pub(crate) fn collection_file(index: usize, name: &str) -> String {
    format!("collections/c{index:02}_{name}.mcap")
}

/// Writes `path` through a temp file in the same directory and renames it into place.
pub(crate) fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), DatasetError> {
    use std::io::Write;
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("file");
    let tmp = path.with_file_name(format!(".{name}.tmp"));
    let result = (|| {
        let file = std::fs::File::create(&tmp)?;
        let mut w = std::io::BufWriter::new(file);
        write(&mut w)?;
        w.flush()?;
        w.into_inner().map_err(|e| e.into_error())?.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        DatasetError::io(path, e)
    })
}

/// The object mesh as a scene augmentation places it: scaled, tilted, re-rested on the table.
/// Returns the mesh and its offset from the turntable axis.
pub(crate) fn placed_mesh(
    mesh: &Mesh,
    augmentation: &Augmentation,
    rng: &mut ChaCha8Rng,
) -> (Mesh, [f32; 2]) {
    let placement = augmentation.scene_placement(rng);
    let mut placed = if placement.tilt != Pose::IDENTITY {
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
    tx: &mpsc::Sender<u64>,
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
            let _ = tx.send(spec.frames_per_sequence as u64);
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
    let on_turntable = Pose::translation([offset[0], offset[1], 0.0]);
    for f in 0..spec.frames_per_sequence {
        let t = f as f32 / spec.fps;
        let world_from_object = Pose::rotation_z(start + omega * t).compose(&on_turntable);
        let frame = render(
            camera,
            &[RenderItem {
                mesh: &mesh,
                world_from_object,
                label: OBJECT_LABEL,
            }],
        );
        let cloud = frame.backproject(camera, OBJECT_LABEL);
        let cloud = subsample(&cloud, spec.max_points_per_view, &mut rng);
        let cloud = augmentation.apply_to_cloud(&cloud, &mut rng);
        sink(f as u32, cloud);
    }
}
