"""Type stubs of the native module ``lgdm._lgdm`` (built from crates/pybridge with maturin).

Use the public names of ``lgdm``; this module is the engine underneath them.
"""

from collections.abc import Iterator
from os import PathLike
from typing import Any, Literal, TypedDict

import numpy as np
import numpy.typing as npt

__version__: str
#: First id of the range used for automatic (per-call) sequence ids: 2**63.
AUTO_SEQUENCE_BASE: int
#: Names of the hyperparameter presets.
PRESETS: list[str]
#: Names of the scenarios, in the paper's order.
SCENARIOS: list[str]
LEARNERS: list[str]

def config_json(text: str) -> str:
    """Parses a config document (JSON, optional ``"preset"`` key, any subset of fields),
    validates it and returns the full config as JSON. Raises ``lgdm.ConfigError``."""

class Model:
    """The native Growing Dual-Memory model. Use ``lgdm.GDM``; this class is its engine.

    Arrays must already be C-contiguous: features float32 (n, d), labels and sequence ids
    int64 (n,), with -1 for "no label".

    Thread-safe: the model sits behind a read-write lock taken with the GIL released. Calls that
    change it (``train``, ``end_episode``, ``replay``) run one at a time, each whole; calls that
    read it run in parallel with each other. A bug (Rust panic) inside a call raises
    ``InternalError`` (an ``lgdm.LgdmError``); after one inside a call that changes the model,
    the model refuses every call with that error."""

    def __init__(self, config: str, dim: int) -> None: ...
    @staticmethod
    def from_bytes(data: bytes) -> Model:
        """Reads a model from checkpoint bytes."""
    @staticmethod
    def load(path: str | PathLike[str]) -> Model:
        """Reads a checkpoint file."""
    def to_bytes(self) -> bytes:
        """The checkpoint bytes."""
    def save(self, path: str | PathLike[str]) -> None:
        """Writes the checkpoint file atomically."""
    def copy(self) -> Model:
        """A deep copy."""
    @property
    def dim(self) -> int:
        """Input dimension."""
    @property
    def n_episodic(self) -> int:
        """Episodic node count."""
    @property
    def n_semantic(self) -> int:
        """Semantic node count."""
    @property
    def size_bytes(self) -> int:
        """Checkpoint size in bytes."""
    @property
    def config_json(self) -> str:
        """The full config as JSON."""
    @property
    def last_sequence(self) -> int | None:
        """Sequence id of the last trained sample, if the next sample could continue it."""
    def train(
        self,
        x: npt.NDArray[np.float32],
        instance: npt.NDArray[np.int64] | None = None,
        category: npt.NDArray[np.int64] | None = None,
        sequence: npt.NDArray[np.int64] | None = None,
        epochs: int = 1,
        end_episodes: bool = False,
    ) -> dict[str, float]:
        """``epochs`` passes (ending an episode after each if ``end_episodes``); returns the
        last pass's statistics. Calls from other threads come before or after, never between
        the passes."""
    def predict(
        self,
        x: npt.NDArray[np.float32],
        sequence: npt.NDArray[np.int64] | None = None,
        no_context: bool = False,
    ) -> tuple[
        npt.NDArray[np.int64],
        npt.NDArray[np.int64],
        npt.NDArray[np.float32],
        npt.NDArray[np.int64],
    ]:
        """``(instance, category, activation, category_em)``; -1 where no label."""
    def evaluate(
        self,
        x: npt.NDArray[np.float32],
        instance: npt.NDArray[np.int64] | None = None,
        category: npt.NDArray[np.int64] | None = None,
        sequence: npt.NDArray[np.int64] | None = None,
        no_context: bool = False,
    ) -> dict[str, float]:
        """Accuracies and quantization errors against the given labels."""
    def end_episode(self) -> None:
        """Ends an episode (isolated-node removal)."""
    def replay(self) -> dict[str, int]:
        """Intrinsic replay; ``{"chains": ..., "samples": ...}``."""
    def _panic_for_tests(self) -> None:
        """Test hook: panics inside the model's exclusive lock, as a bug would. Raises
        ``InternalError`` (an ``lgdm.LgdmError``); the model then refuses every call."""
    def _bench_predict(self, x: npt.NDArray[np.float32], repeats: int = 1) -> list[float]:
        """Seconds of each of ``repeats`` native predict calls (conversion not timed)."""
    def _bench_train(
        self,
        x: npt.NDArray[np.float32],
        instance: npt.NDArray[np.int64] | None = None,
        category: npt.NDArray[np.int64] | None = None,
        repeats: int = 1,
    ) -> list[float]:
        """Seconds of each of ``repeats`` native train calls, each on a fresh copy."""

class Dataset:
    """A dataset directory written by ``lgdm gen-dataset`` (manifest.json + one MCAP file per
    collection). Opening checks the manifest and every collection file's size; raises
    ``lgdm.DatasetError`` if the dataset is missing, incomplete or corrupt."""

    def __init__(self, path: str | PathLike[str]) -> None: ...
    @property
    def path(self) -> str:
        """The dataset directory."""
    @property
    def manifest(self) -> dict[str, Any]:
        """The whole manifest as a dict."""
    @property
    def categories(self) -> list[str]:
        """Category names; a category id is an index into this list."""
    @property
    def instances(self) -> list[dict[str, Any]]:
        """Objects as dicts (``name``, ``category`` id, ``source``); an instance id indexes
        this list."""
    @property
    def collections(self) -> list[dict[str, Any]]:
        """Collections as dicts (``index``, ``name``, ``augmentation``, ``split``, ``file``,
        ``sequences``, ``views``, ...)."""
    def split(self, name: Literal["train", "test"]) -> list[int]:
        """Indices of the collections of a split."""
    def sequences(self, collection: int) -> SequenceIter:
        """Iterates ``(frames, info)`` per object sequence of a collection: ``frames`` a list of
        (N, 3) float32 arrays in metres, ``info`` the labels (see ``SequenceInfo``)."""

class SequenceInfo(TypedDict):
    """Labels of one sequence, as ``Dataset.sequences`` yields them."""

    collection: int
    category: int
    instance: int
    sequence: int
    collection_name: str
    category_name: str
    instance_name: str
    colors: list[npt.NDArray[np.uint8]] | None

class SequenceIter(Iterator[tuple[list[npt.NDArray[np.float32]], SequenceInfo]]):
    """Iterator over one collection's sequences."""

    def __iter__(self) -> SequenceIter: ...
    def __next__(self) -> tuple[list[npt.NDArray[np.float32]], SequenceInfo]: ...

def good_descriptor(points: npt.NDArray[np.float32], bins: int = 15) -> npt.NDArray[np.float32]:
    """The GOOD descriptor (3·bins² values) of an (N, 3) float32 C-contiguous cloud."""

def good_features(dataset: Dataset, bins: int = 15) -> dict[str, Any]:
    """GOOD features of every view of a dataset with their labels, the manifest's train and
    test collections, category names, dataset directory and encoder name."""

def scenario_defaults(name: str) -> dict[str, Any]:
    """A scenario's defaults: preset, replay, epochs, trials, eval_samples, jobs."""

def run_scenario(
    features_: npt.NDArray[np.float32],
    collection: npt.NDArray[np.int64],
    category: npt.NDArray[np.int64],
    instance: npt.NDArray[np.int64],
    sequence: npt.NDArray[np.int64],
    frame: npt.NDArray[np.int64],
    train_collections: list[int],
    test_collections: list[int],
    categories: list[str],
    scenario_name: str,
    *,
    instances: list[str] = ...,
    config: str | None = None,
    trials: int | None = None,
    seed: int = 0,
    replay: bool | None = None,
    context: bool = True,
    epochs: int | None = None,
    eval_every: int | None = None,
    eval_samples: int | None = None,
    train_samples: int = 0,
    validate: bool = False,
    jobs: int | None = None,
    encoder: str = "good",
    dataset: str = "",
    hyperparameters_from: str = "",
    out: str | None = None,
    force: bool = False,
    resume: bool = False,
    learner: str | None = None,
    return_models: bool = False,
) -> tuple[str, list[Model]]:
    """Runs a scenario over trials; ``(metrics.json text, final models)``. With ``out`` it
    writes (``resume``: finishes) a run directory as ``lgdm train`` does."""

def merge_runs(runs: list[str], out: str, *, force: bool = False) -> str:
    """``lgdm merge`` (``lgdm.merge_runs``): the merged run's metrics.json text."""

def generate_dataset(
    out: str,
    preset: str = "small",
    seed: int = 0,
    *,
    frames: int | None = None,
    grasp_images: int | None = None,
    meshes: str | None = None,
    units: list[str] | None = None,
    ycb_from: str | None = None,
    category_map: str | None = None,
) -> Dataset:
    """Generates a dataset as ``lgdm gen-dataset`` does and opens it; ``units`` are
    ``--units`` entries (``"mm"``, ``"<category>/<file>=cm"``); ``ycb_from`` and
    ``category_map`` go with ``preset="ycb"``."""

def project_to_image(
    points: npt.NDArray[np.float32],
    colors: npt.NDArray[np.uint8] | None = None,
    size: int = 224,
    margin: float = 0.08,
    splat_px: int = 0,
) -> dict[str, npt.NDArray[Any] | None]:
    """``depth_m``, ``depth_normalized`` (size, size) float32 and ``rgb`` (size, size, 3)
    uint8 or None: the cloud projected to a square image."""

def view_entropy(points: npt.NDArray[np.float32]) -> float:
    """Viewpoint entropy (nats) of an (N, 3) float32 cloud."""

def best_view(views: list[npt.NDArray[np.float32]]) -> int | None:
    """Index of the view with the highest viewpoint entropy."""

def sim_grasp(
    *,
    scenario_name: str,
    grasp: Any,
    rounds: int,
    seed: int,
    instances: int,
    meshes: str | None,
    units: list[str],
    config_file: str | None,
    gripper: str | None,
    draw: str | None,
    shapes: str | None,
    proposal_check: str | None,
    out: str | None,
    force: bool,
    record_all: bool,
    record_rounds: int | None,
    progress: Any | None,
) -> str:
    """``lgdm sim grasp`` (``lgdm.sim.grasp``): results.json's text."""

def sim_pick_place(
    *,
    scenario_name: str,
    grasp: Any,
    rounds: int | None,
    attempts: int | None,
    seed: int,
    objects_n: int,
    object_seed: int,
    meshes: str | None,
    units: list[str],
    model: str | None,
    replay: bool,
    learn_always: bool,
    encoder: Any,
    confidence: float | None,
    targets: list[str] | None,
    arrive_after: int | None,
    config_file: str | None,
    gripper: str | None,
    draw: str | None,
    shapes: str | None,
    proposal_check: str | None,
    out: str | None,
    force: bool,
    record_all: bool,
    record_rounds: int | None,
    progress: Any | None,
) -> str:
    """``lgdm sim pick-place`` / ``packing`` (``lgdm.sim``): results.json's text."""

def sim_resume(run_dir: str, *, grasp: Any | None, progress: Any | None) -> str:
    """Finishes the interrupted sim run in ``run_dir`` (``lgdm.sim.resume``): results.json's
    text."""

def sim_decode_grasps(
    quality: Any,
    cos2t: Any,
    sin2t: Any,
    width: Any,
    *,
    num_grasps: int = 1,
    jaw_side_fraction: float | None = None,
    crop_px: int | None = None,
    decode: dict[str, float] | None = None,
) -> list[dict[str, Any]]:
    """The grasp autoencoder's maps decoded by the Rust decoder (``lgdm.sim.decode_grasps``)."""
