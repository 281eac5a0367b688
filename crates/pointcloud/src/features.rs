//! Feature tables: one row per view with its labels, computed with GOOD over a whole dataset
//! and stored as `.npz` (arrays `features` (n×dim, float32), `collection`, `category`,
//! `instance`, `frame` (uint32) and `sequence` (uint64)) so numpy reads it directly.
//!
//! ```no_run
//! use lgdm_pointcloud::dataset::Dataset;
//! use lgdm_pointcloud::features::{good_features, FeatureTable};
//! let ds = Dataset::open("data".as_ref()).unwrap();
//! let table = good_features(&ds, 15, &mut |_| {}).unwrap();
//! table.write_npz("features.npz".as_ref()).unwrap();
//! assert_eq!(FeatureTable::read_npz("features.npz".as_ref()).unwrap(), table);
//! ```

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::dataset::{Dataset, DatasetError, Manifest};
use crate::good::good_descriptor_into;
use crate::npz::{NpyRef, NpzError, read_npz, write_npz};
use crate::progress::{Progress, par_map_with_progress};

/// The largest `features` array a table may hold, in bytes: 4 GiB - 1, what an `.npz` without
/// zip64 holds ([`crate::npz::write_npz`]).
pub const MAX_TABLE_BYTES: u64 = u32::MAX as u64;

/// Features of many views with their labels; row `i` belongs to `collection[i]`,
/// `category[i]`, `instance[i]`, `sequence[i]` (unique per collection × object) and `frame[i]`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FeatureTable {
    /// Feature length.
    pub dim: usize,
    /// Row-major `len() × dim` values.
    pub features: Vec<f32>,
    /// Collection index per row.
    pub collection: Vec<u32>,
    /// Category id per row.
    pub category: Vec<u32>,
    /// Instance id per row.
    pub instance: Vec<u32>,
    /// Sequence id per row: `collection × instances + instance`.
    pub sequence: Vec<u64>,
    /// Frame index within the sequence per row.
    pub frame: Vec<u32>,
}

impl FeatureTable {
    /// An empty table of feature length `dim`.
    pub fn new(dim: usize) -> Self {
        Self {
            dim,
            ..Self::default()
        }
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.collection.len()
    }

    /// Whether the table has no rows.
    pub fn is_empty(&self) -> bool {
        self.collection.is_empty()
    }

    /// Features of row `i`.
    pub fn row(&self, i: usize) -> &[f32] {
        &self.features[i * self.dim..(i + 1) * self.dim]
    }

    /// Appends all rows of `other` (same `dim`).
    pub fn extend(&mut self, other: FeatureTable) {
        assert_eq!(self.dim, other.dim, "feature tables of different dimension");
        self.features.extend(other.features);
        self.collection.extend(other.collection);
        self.category.extend(other.category);
        self.instance.extend(other.instance);
        self.sequence.extend(other.sequence);
        self.frame.extend(other.frame);
    }

    /// Checks that every column has `len()` entries and `features` has `len() × dim`.
    pub fn check(&self) -> Result<(), String> {
        let n = self.len();
        for (name, len) in [
            ("category", self.category.len()),
            ("instance", self.instance.len()),
            ("sequence", self.sequence.len()),
            ("frame", self.frame.len()),
        ] {
            if len != n {
                return Err(format!(
                    "column `{name}` has {len} rows, `collection` has {n}"
                ));
            }
        }
        if self.features.len() != n * self.dim {
            return Err(format!(
                "`features` holds {} values, expected {n} rows × {} = {}",
                self.features.len(),
                self.dim,
                n * self.dim
            ));
        }
        Ok(())
    }

    /// Writes the table as an uncompressed `.npz` (temp file + rename).
    pub fn write_npz(&self, path: &Path) -> Result<(), NpzError> {
        self.check().map_err(|reason| NpzError::Format {
            path: path.to_path_buf(),
            reason,
        })?;
        let n = [self.len()];
        let nd = [self.len(), self.dim];
        write_npz(
            path,
            &[
                ("features", NpyRef::F32(&self.features, &nd)),
                ("collection", NpyRef::U32(&self.collection, &n)),
                ("category", NpyRef::U32(&self.category, &n)),
                ("instance", NpyRef::U32(&self.instance, &n)),
                ("sequence", NpyRef::U64(&self.sequence, &n)),
                ("frame", NpyRef::U32(&self.frame, &n)),
            ],
        )
    }

    /// Reads a table written by [`FeatureTable::write_npz`] (or by numpy with the same array
    /// names; integer label arrays of any integer dtype are accepted).
    pub fn read_npz(path: &Path) -> Result<FeatureTable, NpzError> {
        Self::read_npz_checked(path, false)
    }

    /// [`FeatureTable::read_npz`] that also requires exactly the dtypes
    /// [`FeatureTable::write_npz`] writes (`features` float32, `sequence` uint64, the other
    /// labels uint32): for files this crate wrote itself, such as the feature cache.
    pub fn read_npz_exact(path: &Path) -> Result<FeatureTable, NpzError> {
        Self::read_npz_checked(path, true)
    }

    fn read_npz_checked(path: &Path, exact_dtypes: bool) -> Result<FeatureTable, NpzError> {
        let format = |reason: String| NpzError::Format {
            path: path.to_path_buf(),
            reason,
        };
        let arrays = read_npz(path)?;
        if exact_dtypes {
            for (name, dtype) in [
                ("features", "<f4"),
                ("collection", "<u4"),
                ("category", "<u4"),
                ("instance", "<u4"),
                ("sequence", "<u8"),
                ("frame", "<u4"),
            ] {
                if let Some(a) = arrays.iter().find(|a| a.name == name)
                    && a.data.dtype() != dtype
                {
                    return Err(format(format!(
                        "`{name}` has dtype {}, expected {dtype}",
                        a.data.dtype()
                    )));
                }
            }
        }
        let get = |name: &str| {
            arrays
                .iter()
                .find(|a| a.name == name)
                .ok_or_else(|| format(format!("no array `{name}`")))
        };
        let features = get("features")?;
        if features.shape.len() != 2 {
            return Err(format(format!(
                "`features` has shape {:?}, expected (n, dim)",
                features.shape
            )));
        }
        let (n, dim) = (features.shape[0], features.shape[1]);
        let labels = |name: &str| -> Result<Vec<u64>, NpzError> {
            let a = get(name)?;
            if a.shape != [n] {
                return Err(format(format!(
                    "`{name}` has shape {:?}, expected ({n},)",
                    a.shape
                )));
            }
            a.data
                .to_u64()
                .ok_or_else(|| format(format!("`{name}` must hold non-negative integers")))
        };
        let small = |name: &str| -> Result<Vec<u32>, NpzError> {
            labels(name)?
                .into_iter()
                .map(|v| {
                    u32::try_from(v).map_err(|_| format(format!("`{name}` value {v} exceeds u32")))
                })
                .collect()
        };
        Ok(FeatureTable {
            dim,
            features: features.data.to_f32(),
            collection: small("collection")?,
            category: small("category")?,
            instance: small("instance")?,
            sequence: labels("sequence")?,
            frame: small("frame")?,
        })
    }

    /// Checks that the table describes `manifest`'s dataset: the column lengths
    /// ([`FeatureTable::check`]), `dim` columns when given (else at least one), one row per
    /// view (`manifest.views` rows, each collection × instance × frame exactly once), labels
    /// in range and consistent with the manifest (the instance's category, the sequence id
    /// [`Manifest::sequence_id`]), each sequence's rows in frame order, and finite features.
    /// The error names the first bad row.
    pub fn check_dataset(&self, manifest: &Manifest, dim: Option<usize>) -> Result<(), String> {
        self.check()?;
        match dim {
            Some(d) if self.dim != d => {
                return Err(format!(
                    "`features` has {} columns, the encoder gives {d}",
                    self.dim
                ));
            }
            None if self.dim == 0 => return Err("`features` has no columns".into()),
            _ => {}
        }
        let n = self.len();
        if n as u64 != manifest.views {
            return Err(format!(
                "{n} rows, the dataset has {} views",
                manifest.views
            ));
        }
        let frames = manifest.frames_per_sequence as u64;
        let mut seen = vec![false; n];
        // The last frame of each sequence so far: the rows of a sequence are its views in frame
        // order (the order every writer uses), so a `frame` column that disagrees is corrupt.
        let mut last_frame: Vec<Option<u32>> = vec![None; n / frames.max(1) as usize];
        for i in 0..n {
            let (c, cat, inst) = (self.collection[i], self.category[i], self.instance[i]);
            let (seq, f) = (self.sequence[i], self.frame[i]);
            if c as usize >= manifest.collections.len() {
                return Err(format!(
                    "row {i}: collection {c} out of range (the dataset has {})",
                    manifest.collections.len()
                ));
            }
            let Some(info) = manifest.instances.get(inst as usize) else {
                return Err(format!(
                    "row {i}: instance {inst} out of range (the dataset has {})",
                    manifest.instances.len()
                ));
            };
            if cat as usize >= manifest.categories.len() {
                return Err(format!(
                    "row {i}: category {cat} out of range (the dataset has {})",
                    manifest.categories.len()
                ));
            }
            if cat != info.category {
                return Err(format!(
                    "row {i}: category {cat}, but instance {inst} is of category {}",
                    info.category
                ));
            }
            let want = manifest.sequence_id(c, inst);
            if seq != want {
                return Err(format!(
                    "row {i}: sequence {seq}, but collection {c}, instance {inst} is sequence {want}"
                ));
            }
            if u64::from(f) >= frames {
                return Err(format!(
                    "row {i}: frame {f} out of range ({frames} frames per sequence)"
                ));
            }
            let view = seq
                .checked_mul(frames)
                .and_then(|v| v.checked_add(u64::from(f)))
                .and_then(|v| usize::try_from(v).ok())
                .filter(|&v| v < n)
                .ok_or_else(|| {
                    format!("row {i}: view (sequence {seq}, frame {f}) beyond the {n} views")
                })?;
            if std::mem::replace(&mut seen[view], true) {
                return Err(format!(
                    "row {i}: collection {c}, instance {inst}, frame {f} appears twice"
                ));
            }
            // `view < n` above, so `seq < n / frames`.
            let previous = last_frame[seq as usize].replace(f);
            if let Some(p) = previous.filter(|&p| p > f) {
                return Err(format!(
                    "row {i}: collection {c}, instance {inst}, frame {f} comes after its frame \
                     {p}: a sequence's rows must be in frame order"
                ));
            }
        }
        if let Some(k) = self.features.iter().position(|v| !v.is_finite()) {
            return Err(format!(
                "row {}, column {}: feature value {} is not finite",
                k / self.dim,
                k % self.dim,
                self.features[k]
            ));
        }
        Ok(())
    }
}

/// GOOD descriptors (`bins` per side, in `1..=`[`MAX_BINS`](crate::good::MAX_BINS); `3 × bins²`
/// values) of every view of every collection, in collection, file and frame order. Collections
/// are processed in parallel (rayon); the result does not depend on the number of threads.
/// `progress` is called on the calling thread. A table larger than [`MAX_TABLE_BYTES`] (e.g.
/// more than 69 bins for the 75,000 views of the paper preset) is refused before any work.
pub fn good_features(
    ds: &Dataset,
    bins: usize,
    progress: &mut dyn FnMut(Progress),
) -> Result<FeatureTable, DatasetError> {
    if crate::good::check_bins(bins).is_err() {
        return Err(DatasetError::InvalidSpec {
            field: "bins",
            reason: format!("must be in 1..={} (got {bins})", crate::good::MAX_BINS),
        });
    }
    let manifest = ds.manifest();
    let n_coll = manifest.collections.len();
    let dim = 3 * bins * bins;
    let total = manifest.views;
    // The whole table must fit in memory and in an `.npz` (no zip64): refuse before computing.
    let bytes = total.saturating_mul(4 * dim as u64);
    if bytes > MAX_TABLE_BYTES {
        return Err(DatasetError::InvalidSpec {
            field: "bins",
            reason: format!(
                "{total} views × {dim} values ({bins} bins) need {:.1} GiB, more than a feature \
                 table holds (4 GiB, the .npz limit); use fewer bins",
                bytes as f64 / f64::from(1u32 << 30),
            ),
        });
    }
    let cancel = AtomicBool::new(false);
    let mut done = 0;
    let parts = par_map_with_progress(
        n_coll,
        |c, tick| {
            if cancel.load(Ordering::SeqCst) {
                return Err(DatasetError::Cancelled);
            }
            let r = collection_features(ds, c as u32, bins, dim, tick, &cancel);
            if r.is_err() {
                cancel.store(true, Ordering::SeqCst);
            }
            r
        },
        &mut |n| {
            done += n;
            progress(Progress {
                stage: "features",
                done,
                total,
            });
        },
    );
    let mut table = FeatureTable::new(dim);
    let mut first_err = None;
    for part in parts {
        match part {
            Ok(t) => table.extend(t),
            Err(DatasetError::Cancelled) => {}
            Err(e) => {
                first_err.get_or_insert(e);
            }
        }
    }
    if let Some(e) = first_err {
        return Err(e);
    }
    if table.len() as u64 != total {
        return Err(DatasetError::Cancelled);
    }
    Ok(table)
}

fn collection_features(
    ds: &Dataset,
    c: u32,
    bins: usize,
    dim: usize,
    tick: &dyn Fn(u64),
    cancel: &AtomicBool,
) -> Result<FeatureTable, DatasetError> {
    let manifest = ds.manifest();
    let mut table = FeatureTable::new(dim);
    for seq in ds.sequences(c)? {
        if cancel.load(Ordering::SeqCst) {
            return Err(DatasetError::Cancelled);
        }
        let seq = seq?;
        let sequence = manifest.sequence_id(seq.collection, seq.instance);
        for (f, cloud) in seq.frames.iter().enumerate() {
            let start = table.features.len();
            table.features.resize(start + dim, 0.0);
            good_descriptor_into(&cloud.points, bins, &mut table.features[start..]).map_err(
                |source| DatasetError::Good {
                    collection: c,
                    instance: seq.instance,
                    frame: f as u32,
                    source,
                },
            )?;
            table.collection.push(c);
            table.category.push(seq.category);
            table.instance.push(seq.instance);
            table.sequence.push(sequence);
            table.frame.push(f as u32);
        }
        tick(seq.frames.len() as u64);
    }
    Ok(table)
}
