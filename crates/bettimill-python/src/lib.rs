//! `bettimill._bettimill`, the extension module of the `bettimill` Python package
//! (`python/`). It is a thin binding: every answer comes from the crates the CLI uses, so
//! that Python and the CLI cannot disagree.
//!
//! - `topology`: an array's Betti numbers, with the checks and messages of
//!   `bettimill betti` (`bettimill_grid::npy`) and its computation
//!   (`bettimill_homology::topology`). The array is borrowed, in any memory order, and read
//!   once into a [`BinaryImage`] with the GIL released.
//! - `PyPlan`: a manifest's plan (`bettimill_plan::Plan`) and its samples, made by
//!   `bettimill_sample::make_sample` from `Plan::task`, the same path the build's workers
//!   take, so `plan.sample(i)` equals `KEY.npy` and `KEY.json` of the built dataset.
//! - `build` and `verify`: `bettimill_executor` and `bettimill_format`, in this process
//!   or with worker processes of the console script.
//! - `run_cli`: the `bettimill` command line itself (`bettimill_cli::run_as`), for the
//!   package's console script.
//!
//! Threads: every computation runs on `WorkPool`, a rayon pool the module owns, never on
//! rayon's global pool. A process made by `fork` (a DataLoader's workers on Linux) inherits
//! the parent's memory but none of its threads, so a pool made before the fork would take
//! the child's work and never run it; the module notices the new process id and makes a
//! fresh pool there. rayon's global pool cannot be made again, so nothing here uses it.
//!
//! Errors: bad input is `ValueError` (a missing file `FileNotFoundError`, a failed write
//! `OSError`, an array or sample larger than the memory available `MemoryError`) with the
//! message the CLI prints after `error: `. Nothing here prints.

use bettimill_executor::coordinator::{self, BuildControl};
use bettimill_executor::{BuildFailure, BuildRequest, Runner};
use bettimill_grid::npy;
use bettimill_grid::BinaryImage;
use bettimill_manifest::{Manifest, DEMO_MANIFEST};
use bettimill_plan::Plan;
use numpy::ndarray::{ArrayD, IxDyn};
use numpy::{
    PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::exceptions::{
    PyFileNotFoundError, PyIndexError, PyKeyboardInterrupt, PyMemoryError, PyOSError, PyValueError,
};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyRange};
use std::ffi::OsString;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

fn value_error(err: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(err.to_string())
}

/// The module's rayon pool for this process, and the thread count asked for.
struct WorkPool {
    /// The process the pool's threads run in; another id means this is a forked child.
    pid: u32,
    /// Threads asked for by `set_threads`; 0 is rayon's default (`RAYON_NUM_THREADS`, else
    /// one per core).
    threads: usize,
    pool: Option<Arc<rayon::ThreadPool>>,
}

static WORK_POOL: Mutex<WorkPool> = Mutex::new(WorkPool {
    pid: 0,
    threads: 0,
    pool: None,
});

impl WorkPool {
    /// The pool of this process, made on first use and again after a fork.
    fn current() -> PyResult<Arc<rayon::ThreadPool>> {
        let mut slot = WORK_POOL.lock().unwrap_or_else(PoisonError::into_inner);
        let pid = std::process::id();
        if slot.pid != pid {
            // The parent's pool: its threads do not exist here, and dropping it would
            // signal them through locks their last state may hold, so it is left alone.
            if let Some(inherited) = slot.pool.take() {
                std::mem::forget(inherited);
            }
            slot.pid = pid;
        }
        if let Some(pool) = &slot.pool {
            return Ok(Arc::clone(pool));
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(slot.threads)
            .thread_name(|i| format!("bettimill-{i}"))
            .build()
            .map_err(|err| {
                PyOSError::new_err(format!("cannot start bettimill's threads: {err}"))
            })?;
        let pool = Arc::new(pool);
        slot.pool = Some(Arc::clone(&pool));
        Ok(pool)
    }

    /// Asks for `threads` threads (0: rayon's default) from the next computation on.
    fn set_threads(threads: usize) {
        let mut slot = WORK_POOL.lock().unwrap_or_else(PoisonError::into_inner);
        if slot.threads != threads {
            slot.threads = threads;
            // A pool of this process ends its threads when its last user drops it; one
            // inherited from the parent is left alone, as in `current`.
            if slot.pid != std::process::id() {
                if let Some(inherited) = slot.pool.take() {
                    std::mem::forget(inherited);
                }
            }
            slot.pool = None;
        }
    }

    fn threads() -> PyResult<usize> {
        Ok(WorkPool::current()?.current_num_threads())
    }
}

/// `py.detach(work)` on the module's pool: the GIL released, and every rayon call of `work`
/// on this process's own threads.
fn detach_in_pool<T, F>(py: Python<'_>, work: F) -> PyResult<T>
where
    T: Send,
    F: Send + FnOnce() -> T,
{
    let pool = WorkPool::current()?;
    Ok(py.detach(|| pool.install(work)))
}

/// Reads one borrowed numpy array of element type `T` into an image, GIL released.
fn image_of<T>(py: Python<'_>, array: &Bound<'_, PyAny>, strict: bool) -> PyResult<BinaryImage>
where
    T: numpy::Element + Copy + Into<i128> + Sync,
{
    let array: PyReadonlyArrayDyn<'_, T> = array.cast::<PyArrayDyn<T>>()?.readonly();
    let view = array.as_array();
    let shape = view.shape().to_vec();
    py.detach(|| match view.as_slice() {
        // C order: the memory is the order of the values.
        Some(slice) => npy::image_from_values(&shape, slice.iter().copied(), strict),
        // Any other layout: the view's iterator walks it in C order, without a copy.
        None => npy::image_from_values(&shape, view.iter().copied(), strict),
    })
    .map_err(value_error)
}

/// The numpy array `array` as a binary image, with the checks of reading a `.npy` file:
/// bool or integer dtype, 2 to 4 axes, none empty, and with `strict` only 0 and 1.
fn read_array(py: Python<'_>, array: &Bound<'_, PyAny>, strict: bool) -> PyResult<BinaryImage> {
    let untyped = array.cast::<PyUntypedArray>().map_err(|_| {
        PyValueError::new_err(format!(
            "expected a numpy array, got {}",
            array
                .get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default()
        ))
    })?;
    let descr: String = untyped.dtype().getattr("str")?.extract()?;
    let dtype = npy::parse_dtype(&descr).map_err(value_error)?;
    // The shape is checked before the dtype's byte order matters, as a file's would be.
    npy::check_shape(untyped.shape()).map_err(value_error)?;
    // And against the memory available before anything is allocated: a broadcast array
    // of 10^12 ones takes no memory in numpy, but its copy here would, and a failed
    // allocation aborts the interpreter.
    let padded = untyped
        .shape()
        .iter()
        .fold(1u64, |n, &side| n.saturating_mul(side as u64 + 2));
    bettimill_plan::memory::admit_image("the array", untyped.ndim(), padded)
        .map_err(|refusal| PyMemoryError::new_err(refusal.to_string()))?;
    if dtype.big_endian && dtype.size > 1 {
        return Err(PyValueError::new_err(format!(
            "dtype {descr:?} is big-endian: convert it with array.astype(array.dtype.newbyteorder('='))"
        )));
    }
    match (dtype.kind, dtype.size) {
        ('b', 1) => image_of::<bool>(py, array, strict),
        ('u', 1) => image_of::<u8>(py, array, strict),
        ('i', 1) => image_of::<i8>(py, array, strict),
        ('u', 2) => image_of::<u16>(py, array, strict),
        ('i', 2) => image_of::<i16>(py, array, strict),
        ('u', 4) => image_of::<u32>(py, array, strict),
        ('i', 4) => image_of::<i32>(py, array, strict),
        ('u', 8) => image_of::<u64>(py, array, strict),
        ('i', 8) => image_of::<i64>(py, array, strict),
        _ => Err(value_error(npy::NpyError::Dtype(descr))),
    }
}

/// `bettimill.topology(array, strict=False)`: what `bettimill betti --json` prints for the
/// array saved as `.npy` (betti, euler, shape, hypervolume, field), plus `components` (b0).
#[pyfunction]
#[pyo3(signature = (array, strict = false))]
fn topology<'py>(
    py: Python<'py>,
    array: &Bound<'py, PyAny>,
    strict: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let image = read_array(py, array, strict)?;
    let shape = image.shape().to_vec();
    // The image is not needed afterwards: padded in place, one copy at the peak.
    let (topology, hypervolume) = detach_in_pool(py, || {
        let hypervolume = image.count_foreground();
        (bettimill_homology::try_topology_owned(image), hypervolume)
    })?;
    // An image too large (or too large and rough) for the exact route is a ValueError,
    // never a panic.
    let topology = topology.map_err(|error| PyValueError::new_err(error.to_string()))?;
    let dict = PyDict::new(py);
    dict.set_item("betti", &topology.betti)?;
    dict.set_item("euler", topology.euler)?;
    dict.set_item("shape", shape)?;
    dict.set_item("hypervolume", hypervolume)?;
    dict.set_item("field", "Z/2")?;
    dict.set_item("components", topology.betti[0])?;
    Ok(dict)
}

/// Parses JSON text into Python objects with Python's own `json` module, so a label is the
/// same dict `json.loads` gives for `KEY.json`.
fn json_to_py<'py>(py: Python<'py>, text: &str) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.call_method1("loads", (text,))
}

/// Where a manifest came from: its text and the name its errors carry.
struct Source {
    text: String,
    origin: PathBuf,
}

/// A manifest given as a path (str or os.PathLike), the name of a preset (a file of the
/// repository's `manifests/`, built in: `demo-3d`), TOML text (a str with a newline or an
/// `=`), or None for the embedded demo manifest (what `bettimill build` builds without one).
fn manifest_source(source: Option<&Bound<'_, PyAny>>) -> PyResult<Source> {
    let Some(source) = source.filter(|s| !s.is_none()) else {
        return Ok(Source {
            text: DEMO_MANIFEST.to_string(),
            origin: PathBuf::from("<embedded demo manifest>"),
        });
    };
    if let Ok(text) = source.extract::<String>() {
        if text.trim().is_empty() {
            return Err(PyValueError::new_err(
                "the manifest is an empty string: give a path, TOML text, or None for the demo manifest",
            ));
        }
        // A str over the manifest size limit is no path or preset name either: it is text,
        // which parsing refuses as it refuses such a file, without repeating it.
        let oversized = text.len() as u64 > bettimill_manifest::MAX_MANIFEST_BYTES;
        if oversized || text.contains('\n') || text.contains('=') {
            return Ok(Source {
                text,
                origin: PathBuf::from("<manifest text>"),
            });
        }
    }
    let path: PathBuf = source.extract().map_err(|_| {
        PyValueError::new_err(
            "a manifest is a preset name, a path, TOML text, or None for the demo manifest",
        )
    })?;
    if !path.exists() {
        // A name that is no file here: a preset, wherever the program runs.
        if let Some(text) = path.to_str().and_then(bettimill_manifest::preset) {
            return Ok(Source {
                text: text.to_string(),
                origin: PathBuf::from(format!("<preset {}>", path.display())),
            });
        }
        let names: Vec<&str> = bettimill_manifest::PRESETS
            .iter()
            .map(|(n, _)| *n)
            .collect();
        return Err(PyFileNotFoundError::new_err(format!(
            "cannot read the manifest {}: no such file, and no preset of that name (the presets: {})",
            shortened(&path.to_string_lossy()),
            names.join(", ")
        )));
    }
    let text = bettimill_manifest::read_text(&path).map_err(value_error)?;
    Ok(Source { text, origin: path })
}

/// A name as an error shows it: at most 200 characters, saying how many more there were, so
/// a long string that is neither a file nor TOML is not printed back whole.
fn shortened(name: &str) -> String {
    const SHOWN: usize = 200;
    match name.char_indices().nth(SHOWN) {
        Some((cut, _)) => format!(
            "{}... ({} more characters)",
            &name[..cut],
            name[cut..].chars().count()
        ),
        None => name.to_string(),
    }
}

fn parse_manifest(source: &Source) -> PyResult<Manifest> {
    Manifest::parse(&source.text, &source.origin).map_err(value_error)
}

/// `bettimill.Plan(manifest=None)`: the plan of a manifest (a preset name, a path, TOML
/// text, or None for the demo manifest) and its samples, made on demand.
#[pyclass(name = "Plan", module = "bettimill", frozen)]
struct PyPlan {
    plan: Arc<Plan>,
    text: String,
    origin: PathBuf,
    /// The process whose memory was found to hold a sample (0: none yet). Every sample of
    /// a plan has the same size, and reading the machine's memory costs more than making a
    /// small sample, so each process checks once (a DataLoader worker is a new process).
    admitted: AtomicU32,
}

impl PyPlan {
    fn from_source(source: Source) -> PyResult<PyPlan> {
        let manifest = parse_manifest(&source)?;
        let plan = Plan::new(&manifest).map_err(value_error)?;
        Ok(PyPlan {
            plan: Arc::new(plan),
            text: source.text,
            origin: source.origin,
            admitted: AtomicU32::new(0),
        })
    }

    /// Refuses a sample the machine cannot hold, before it is made (the CLI refuses such a
    /// plan with the same estimate; a failed allocation, such as a 4D side-254 sample's,
    /// would abort the interpreter).
    /// The answer depends only on the plan and the machine, so it is checked once per
    /// process: a forked worker checks again.
    fn admit(&self, index: u64) -> PyResult<()> {
        let pid = std::process::id();
        if self.admitted.load(Ordering::Relaxed) != pid {
            let voxels = (self.plan.side as u64).saturating_pow(self.plan.dimension.get() as u32);
            bettimill_plan::memory::admit_image(
                &format!("sample {index}"),
                self.plan.dimension.get(),
                voxels,
            )
            .map_err(|refusal| PyMemoryError::new_err(refusal.to_string()))?;
            self.admitted.store(pid, Ordering::Relaxed);
        }
        Ok(())
    }

    fn index(&self, index: i64) -> PyResult<u64> {
        let n = self.plan.samples as i64;
        let i = if index < 0 { index + n } else { index };
        if i < 0 || i >= n {
            return Err(PyIndexError::new_err(format!(
                "sample {index} of a plan with {n} samples"
            )));
        }
        Ok(i as u64)
    }
}

#[pymethods]
impl PyPlan {
    #[new]
    #[pyo3(signature = (manifest = None))]
    fn new(manifest: Option<&Bound<'_, PyAny>>) -> PyResult<PyPlan> {
        PyPlan::from_source(manifest_source(manifest)?)
    }

    fn __len__(&self) -> usize {
        self.plan.samples as usize
    }

    fn __repr__(&self) -> String {
        format!(
            "Plan({:?}: {} samples, {}D, side {}, {} strata)",
            self.plan.name,
            self.plan.samples,
            self.plan.dimension,
            self.plan.side,
            self.plan.strata.len()
        )
    }

    /// Pickling (a DataLoader's workers under spawn): the manifest text, replanned there.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(Bound<'py, PyAny>, (String, PathBuf))> {
        let py = slf.py();
        let plan = slf.get();
        let rebuild = py
            .import("bettimill._bettimill")?
            .getattr("_plan_from_text")?;
        Ok((rebuild, (plan.text.clone(), plan.origin.clone())))
    }

    /// The dataset name (the prefix of every shard).
    #[getter]
    fn name(&self) -> &str {
        &self.plan.name
    }

    /// Number of axes.
    #[getter]
    fn dimension(&self) -> usize {
        self.plan.dimension.get()
    }

    /// Voxels per axis.
    #[getter]
    fn side(&self) -> u32 {
        self.plan.side
    }

    /// The manifest's canonical hash (`manifest_hash` in every label).
    #[getter]
    fn manifest_hash(&self) -> &str {
        &self.plan.manifest_hash
    }

    /// The plan's hash (build.json, the dataset card).
    #[getter]
    fn hash(&self) -> String {
        self.plan.hash()
    }

    /// Side lengths of the downscaled copies every sample carries.
    #[getter]
    fn resolutions(&self) -> Vec<u32> {
        self.plan.resolutions.clone()
    }

    /// The manifest text the plan was made from.
    #[getter]
    fn manifest(&self) -> &str {
        &self.text
    }

    /// Samples per split, in split order.
    #[getter]
    fn splits<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let dict = PyDict::new(py);
        for (name, size) in &self.plan.splits {
            dict.set_item(name, size)?;
        }
        Ok(dict)
    }

    /// The strata (what `KEY.cls` indexes): dicts of cls, name, family, mode, components,
    /// bin (inclusive foreground voxel bounds, or None), betti and count (samples).
    #[getter]
    fn strata<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let list = PyList::empty(py);
        for (stratum, count) in self.plan.strata.iter().zip(self.plan.total_counts()) {
            let dict = PyDict::new(py);
            dict.set_item("cls", stratum.index)?;
            dict.set_item("name", &stratum.label)?;
            dict.set_item("family", stratum.family.label())?;
            dict.set_item("mode", bettimill_plan::mode_name(stratum.mode))?;
            dict.set_item("components", stratum.components)?;
            dict.set_item("bin", stratum.hypervolume)?;
            dict.set_item("betti", &stratum.betti)?;
            dict.set_item("count", count)?;
            list.append(dict)?;
        }
        Ok(list)
    }

    /// The class table (`classes.json` of the built dataset, from `Plan::class_table`):
    /// what every `cls` (stratum) means, and the topology class of each (one per distinct
    /// Betti vector and knot type), with counts.
    #[getter]
    fn classes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let json = serde_json::to_string(&self.plan.class_table()).map_err(value_error)?;
        json_to_py(py, &json)
    }

    /// The sample indices of one split, as a `range` (splits are contiguous).
    fn split<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyRange>> {
        let mut start = 0;
        for (split, size) in &self.plan.splits {
            if split == name {
                return PyRange::new(py, start as isize, (start + size) as isize);
            }
            start += size;
        }
        let names: Vec<&str> = self.plan.splits.iter().map(|(n, _)| n.as_str()).collect();
        Err(PyValueError::new_err(format!(
            "the plan has no split {name:?}; its splits are {names:?}"
        )))
    }

    /// `(voxels, label)` of sample `index`: a uint8 array of 0 and 1 (C order) and the label
    /// dict, equal to `KEY.npy` and `KEY.json` of the built dataset. With `resolution`, the
    /// voxels are that downscaled copy (`KEY.rSIDE.npy`); it must be one of
    /// `plan.resolutions`. The GIL is released while the sample is made.
    #[pyo3(signature = (index, resolution = None))]
    fn sample<'py>(
        &self,
        py: Python<'py>,
        index: i64,
        resolution: Option<u32>,
    ) -> PyResult<(Bound<'py, PyArrayDyn<u8>>, Bound<'py, PyAny>)> {
        let index = self.index(index)?;
        if let Some(side) = resolution {
            if side != self.plan.side && !self.plan.resolutions.contains(&side) {
                return Err(PyValueError::new_err(format!(
                    "resolution {side}: the plan's samples have side {} and downscaled copies {:?}",
                    self.plan.side, self.plan.resolutions
                )));
            }
        }
        self.admit(index)?;
        let plan = Arc::clone(&self.plan);
        let (image, json) = detach_in_pool(py, move || {
            let task = plan.task(index).expect("the index was checked");
            let sample = bettimill_sample::make_sample(&plan, &task)?;
            let json = String::from_utf8(sample.json_bytes()).expect("labels are JSON");
            let image = match resolution {
                Some(side) if side != plan.side => sample
                    .downscaled
                    .into_iter()
                    .find(|d| d.shape()[0] == side as usize)
                    .expect("the resolution was checked"),
                _ => sample.image,
            };
            Ok::<_, bettimill_sample::SampleError>((image, json))
        })?
        .map_err(|err| pyo3::exceptions::PyRuntimeError::new_err(err.to_string()))?;
        Ok((to_array(py, image), json_to_py(py, &json)?))
    }

    /// The undeformed construction of sample `index` at `attempt` (a sample's label records
    /// the attempt it was made at, `label["attempt"]`): a uint8 array of the voxels as
    /// rasterised, before deformation and hypervolume targeting. For measuring how far
    /// deformation took a sample from the shape it was built from; it is not verified and
    /// not part of a dataset.
    #[pyo3(signature = (index, attempt = 0))]
    fn construction<'py>(
        &self,
        py: Python<'py>,
        index: i64,
        attempt: u32,
    ) -> PyResult<Bound<'py, PyArrayDyn<u8>>> {
        let index = self.index(index)?;
        if attempt >= bettimill_sample::MAX_ATTEMPTS {
            return Err(PyValueError::new_err(format!(
                "attempt {attempt}: a sample is made in at most {} attempts",
                bettimill_sample::MAX_ATTEMPTS
            )));
        }
        self.admit(index)?;
        let plan = Arc::clone(&self.plan);
        let image = detach_in_pool(py, move || {
            let task = plan.task(index).expect("the index was checked");
            bettimill_sample::construction(&plan, &task, attempt).map(|c| c.image)
        })?
        .map_err(|err| pyo3::exceptions::PyRuntimeError::new_err(err.to_string()))?;
        Ok(to_array(py, image))
    }
}

/// An image as a numpy uint8 array of its shape, moved without a copy.
fn to_array(py: Python<'_>, image: BinaryImage) -> Bound<'_, PyArrayDyn<u8>> {
    let shape = image.shape().to_vec();
    let array = ArrayD::from_shape_vec(IxDyn(&shape), image.into_vec())
        .expect("an image's data fits its shape");
    PyArrayDyn::from_owned_array(py, array)
}

/// Unpickles a [`PyPlan`] (see `__reduce__`).
#[pyfunction]
fn _plan_from_text(text: String, origin: PathBuf) -> PyResult<PyPlan> {
    PyPlan::from_source(Source { text, origin })
}

/// `bettimill.build(manifest, out, workers=None, worker_program=None)`: builds (or resumes)
/// the dataset of `manifest` in `out`, as `bettimill build` does (the same entry point,
/// `bettimill_executor::build`, with its memory check). With `workers` None or 1 the shards
/// are built in this process; with more, by that many worker processes of `worker_program`
/// (the package's `bettimill` console script). Returns the totals.
/// An `s3://` `out` is built in this process whatever `workers` says, with the AWS
/// variables and `endpoint` (else `AWS_ENDPOINT_URL`), as `bettimill build --out s3://...`.
#[pyfunction]
#[pyo3(signature = (manifest, out, workers = None, worker_program = None, endpoint = None))]
fn build<'py>(
    py: Python<'py>,
    manifest: Option<&Bound<'py, PyAny>>,
    out: PathBuf,
    workers: Option<usize>,
    worker_program: Option<PathBuf>,
    endpoint: Option<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let source = manifest_source(manifest)?;
    let parsed = parse_manifest(&source)?;
    let runner = match workers {
        Some(0) => return Err(PyValueError::new_err("workers must be at least 1")),
        None | Some(1) => Runner::InProcess,
        Some(count) => Runner::Workers {
            count,
            program: worker_program.ok_or_else(|| {
                PyValueError::new_err("workers > 1 needs the bettimill console script")
            })?,
        },
    };
    let request = BuildRequest {
        out,
        manifest_text: source.text,
        manifest: parsed,
        runner,
        max_memory: None,
        max_shard_failures: coordinator::DEFAULT_MAX_SHARD_FAILURES,
        worker_timeout: coordinator::DEFAULT_WORKER_TIMEOUT,
        object: bettimill_executor::remote::ObjectOptions {
            endpoint,
            ..Default::default()
        },
    };
    // Ctrl-C in Python: the interpreter's handler only sets a flag, so a build by worker
    // processes asks for it every 100 ms and stops its workers (resumable, like the CLI's).
    let control = async {
        loop {
            tokio::time::sleep(std::time::Duration::from_millis(100)).await;
            if Python::attach(|py| py.check_signals()).is_err() {
                return BuildControl::Interrupt;
            }
        }
    };
    let report = detach_in_pool(py, || bettimill_executor::build(request, control, |_| {}))?
        .map_err(|err| match err {
            // An in-process build that fails (a full disk, a held lock) is an OSError, as
            // a failed file operation; a refused manifest, plan or directory a ValueError.
            BuildFailure::Lock(_) | BuildFailure::InProcess(_) => {
                PyOSError::new_err(err.to_string())
            }
            err => value_error(err),
        })?;
    let totals = &report.totals;
    if totals.interrupted {
        return Err(PyKeyboardInterrupt::new_err(format!(
            "interrupted: {} of {} shards complete, nothing partial is visible; build again to resume",
            totals.complete, totals.shards
        )));
    }
    if !totals.failed.is_empty() {
        let reasons: Vec<String> = totals
            .failed
            .iter()
            .map(|f| {
                format!(
                    "{}: {}",
                    f.shard,
                    f.reasons.last().map(String::as_str).unwrap_or("")
                )
            })
            .collect();
        return Err(PyOSError::new_err(format!(
            "{} shard(s) failed and were given up; index.json not written:\n{}",
            totals.failed.len(),
            reasons.join("\n")
        )));
    }
    let dict = PyDict::new(py);
    dict.set_item("built", totals.built)?;
    dict.set_item("skipped", totals.skipped)?;
    dict.set_item("regenerations", totals.regenerations)?;
    dict.set_item("workers", workers.unwrap_or(1))?;
    dict.set_item("samples", report.samples)?;
    dict.set_item("shards", totals.shards)?;
    dict.set_item("index", report.index)?;
    Ok(dict)
}

/// `bettimill.verify(dir, endpoint=None)`: what `bettimill verify DIR --json` prints, as a
/// dict; its `problems` list is empty when every shard matches `index.json`. `dir` may be
/// `s3://BUCKET/PREFIX`, read by ranges with the AWS variables and `endpoint` (else
/// `AWS_ENDPOINT_URL`), as the CLI reads it; a server, bucket or key that does not answer
/// is an `OSError` naming the URL.
#[pyfunction]
#[pyo3(signature = (dir, endpoint = None))]
fn verify<'py>(
    py: Python<'py>,
    dir: PathBuf,
    endpoint: Option<String>,
) -> PyResult<Bound<'py, PyAny>> {
    let url = dir
        .to_str()
        .filter(|d| bettimill_shard::object::is_object_url(d))
        .map(str::to_string);
    let report = detach_in_pool(py, || {
        let mut report = match &url {
            Some(url) => bettimill_executor::remote::open_bucket(url, endpoint.as_deref())
                .map_err(|err| PyOSError::new_err(err.to_string()))?
                .verify(&mut |_, _| {})
                .map_err(value_error),
            None => bettimill_format::DatasetDir::new(&dir)
                .verify(&mut |_, _| {})
                .map_err(value_error),
        }?;
        // The files that follow from the plan and the records, as `bettimill verify` checks.
        report
            .problems
            .extend(bettimill_cli::plan_file_problems(&dir, endpoint.as_deref()));
        Ok::<_, PyErr>(report)
    })??;
    let json = serde_json::to_string(&report).map_err(value_error)?;
    json_to_py(py, &json)
}

/// The `bettimill` command line: `args` as `sys.argv` (the program name first), `program`
/// the file that runs it again (for workers). Returns the exit code; the GIL is released.
#[pyfunction]
fn run_cli(py: Python<'_>, args: Vec<OsString>, program: PathBuf) -> PyResult<i32> {
    detach_in_pool(py, || bettimill_cli::run_as(args, program))
}

/// `bettimill.presets()`: the names of the built-in manifests, each accepted wherever a
/// manifest is (`bettimill.Plan("demo-4d")`), with their text.
#[pyfunction]
fn presets<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    for (name, text) in bettimill_manifest::PRESETS {
        dict.set_item(name, text)?;
    }
    Ok(dict)
}

/// `bettimill.set_threads(n)`: the number of threads the module's computations use from now
/// on in this process (0: `RAYON_NUM_THREADS`, else one per core). Returns the count now in
/// force.
#[pyfunction]
fn set_threads(threads: usize) -> PyResult<usize> {
    WorkPool::set_threads(threads);
    WorkPool::threads()
}

/// `bettimill.threads()`: the number of threads the module's computations use.
#[pyfunction]
fn threads() -> PyResult<usize> {
    WorkPool::threads()
}

/// The extension module.
#[pymodule]
fn _bettimill(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(topology, m)?)?;
    m.add_function(wrap_pyfunction!(build, m)?)?;
    m.add_function(wrap_pyfunction!(verify, m)?)?;
    m.add_function(wrap_pyfunction!(run_cli, m)?)?;
    m.add_function(wrap_pyfunction!(_plan_from_text, m)?)?;
    m.add_function(wrap_pyfunction!(set_threads, m)?)?;
    m.add_function(wrap_pyfunction!(presets, m)?)?;
    m.add_function(wrap_pyfunction!(threads, m)?)?;
    m.add_class::<PyPlan>()?;
    m.add("__version__", bettimill_format::TOOL_VERSION)?;
    Ok(())
}
