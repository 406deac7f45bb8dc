"""Shared fixtures, and the two tiers of tests.

The real objects live in ``../shared/data`` next to the checkout (or ``$KINMO_DATA``) and are
never part of the repository. Every test that reads them carries the ``realdata`` marker (added
here to each test whose fixtures include ``shared_data``); without the data those tests are
skipped, the rest run, and the run ends with one line saying how many did not run. With
``KINMO_REQUIRE_DATA=1`` (CI) a missing dataset stops the run before any test: no real-data
test is ever skipped there. Tests that assert facts of our exact set of objects (235 + 141; an
object id, a count the data's README does not state) also carry ``exactdata``.

The browser tests (the ``chromium`` fixture) are skipped when no Chromium is installed, and
required under ``KINMO_REQUIRE_BROWSER=1`` or ``KINMO_REQUIRE_DATA=1``.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

#: How to run the real-data tests, for the skip reason and the closing line.
ENABLE_DATA = "set KINMO_DATA=/path/to/data holding partnet-mobility/ and partnet/"


def data_root() -> Path:
    """The shared dataset folder (``$KINMO_DATA`` or ``<repo>/../shared/data``)."""
    return Path(os.environ.get("KINMO_DATA") or REPO.parent / "shared" / "data")


def data_missing() -> str | None:
    """Why the shared dataset cannot be read (one line), or None when it can."""
    root = data_root()
    absent = [d for d in ("partnet-mobility", "partnet") if not (root / d).is_dir()]
    if len(absent) == 2:
        return f"no shared dataset at {root}"
    return f"{root} has no {absent[0]}/" if absent else None


def required(name: str) -> bool:
    """Whether the environment variable ``name`` is set to something other than empty or 0."""
    return os.environ.get(name, "") not in ("", "0")


def _browser_flag() -> str:
    """The variable that requires the browser, as ``NAME=value`` for messages."""
    name = "KINMO_REQUIRE_BROWSER" if required("KINMO_REQUIRE_BROWSER") else "KINMO_REQUIRE_DATA"
    return f"{name}={os.environ.get(name)}"


def browser_required() -> bool:
    """CI (``KINMO_REQUIRE_DATA=1``) and ``KINMO_REQUIRE_BROWSER=1`` fail without a Chromium."""
    return required("KINMO_REQUIRE_BROWSER") or required("KINMO_REQUIRE_DATA")


#: The shared data's absence (:func:`data_missing`), read once when the run starts.
_MISSING = pytest.StashKey["str | None"]()


def pytest_configure(config: pytest.Config) -> None:
    """Stop at once, in one line, when a required dataset or browser is missing (as
    ``scripts/require.sh`` does before ``scripts/test.sh`` builds anything)."""
    why = data_missing()
    config.stash[_MISSING] = why
    if why and required("KINMO_REQUIRE_DATA"):
        flag = f"KINMO_REQUIRE_DATA={os.environ['KINMO_REQUIRE_DATA']}"
        raise pytest.UsageError(f"{flag} but {why}: {ENABLE_DATA}")
    if browser_required():
        from browser import BROWSERS, find_browser

        if find_browser() is None:
            names = ", ".join(BROWSERS)
            raise pytest.UsageError(f"{_browser_flag()} but no Chromium on PATH (looked for "
                                    f"{names}): install one, see the README's tests")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark every test that reads the shared data ``realdata`` (``exactdata`` implies it)."""
    for item in items:
        reads = "shared_data" in getattr(item, "fixturenames", ()) or item.get_closest_marker("exactdata")
        if reads and item.get_closest_marker("realdata") is None:
            item.add_marker(pytest.mark.realdata)


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    """Skip a real-data test, before its fixtures, when the shared data is missing.

    Raised here rather than by a skip marker so that pytest's summary folds them into one line.
    """
    if item.get_closest_marker("realdata") and item.config.stash[_MISSING]:
        pytest.skip(f"real-data test, no shared dataset: {ENABLE_DATA} to run it")


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_terminal_summary(terminalreporter, exitstatus, config: pytest.Config):
    """After pytest's short summary: one line on the real-data tests that did not run."""
    result = yield
    why = config.stash[_MISSING]
    n = sum(1 for r in terminalreporter.stats.get("skipped", ()) if "realdata" in r.keywords)
    if why and n:
        terminalreporter.write_line(
            f"kinmo: {n} real-data tests did not run ({why}): {ENABLE_DATA} to run them",
            yellow=True, bold=True)
    return result


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The shared dataset folder; every test that uses it (directly or through another
    fixture) is a ``realdata`` test."""
    why = data_missing()
    if why:
        raise FileNotFoundError(f"{why}: {ENABLE_DATA}")
    return data_root()


@pytest.fixture(scope="session")
def mobility_root(shared_data: Path) -> Path:
    return shared_data / "partnet-mobility"


@pytest.fixture(scope="session")
def partnet_root(shared_data: Path) -> Path:
    return shared_data / "partnet"


@pytest.fixture(scope="session")
def data_facts(shared_data: Path) -> dict[str, int]:
    """Counts the shared data's ``README.md`` states, so tests follow the data as it grows.

    Keys: ``mobility_objects``, ``mobility_categories``, ``partnet_shapes``,
    ``partnet_categories``, ``axes``, ``non_unit_axes``, ``rotating_sliders``, ``min_leaves``,
    ``max_leaves``. A README that no longer states one of them fails the test that asks.
    """
    text = (shared_data / "README.md").read_text(encoding="utf-8")
    patterns = {
        ("mobility_objects", "mobility_categories"): r"## partnet-mobility/ \((\d+) objects, (\d+) categories\)",
        ("partnet_shapes", "partnet_categories"): r"## partnet/ \((\d+) shapes, (\d+) categories\)",
        ("non_unit_axes", "axes"): r"(\d+) of the (\d+) axis directions are not of unit length",
        ("rotating_sliders",): r"(\d+) sliders with `rotates`",
        ("min_leaves", "max_leaves"): r"leaf counts from (\d+) to (\d+)",
    }
    facts: dict[str, int] = {}
    for keys, pattern in patterns.items():
        m = re.search(pattern, text)
        if m is None:
            raise AssertionError(f"{shared_data / 'README.md'}: no line matching {pattern!r}")
        facts.update({k: int(v) for k, v in zip(keys, m.groups())})
    return facts


# --- A synthetic PartNet-Mobility cabinet with known labels (kinmo.data tests) -----------

#: Boxes of the synthetic cabinet, y-up: mesh name -> (min corner, max corner).
CABINET_BOXES = {
    "body": ((0.0, 0.1, 0.0), (1.0, 1.0, 0.5)),
    "base": ((0.0, 0.0, 0.0), (1.0, 0.1, 0.5)),
    "door": ((0.0, 0.5, 0.5), (0.5, 1.0, 0.52)),
    "handle": ((0.4, 0.7, 0.52), (0.45, 0.8, 0.56)),
    "drawer_front": ((0.5, 0.1, 0.5), (1.0, 0.5, 0.52)),
    "drawer_box": ((0.55, 0.15, 0.1), (0.95, 0.45, 0.5)),
    "knob": ((0.2, 0.6, 0.52), (0.3, 0.7, 0.55)),
}


def write_box_obj(path: Path, lo, hi) -> None:
    """Write an axis-aligned box as a 12-triangle OBJ (quads split, 1-based indices)."""
    import itertools

    v = [(x, y, z) for x, y, z in itertools.product(*zip(lo, hi))]  # index = 4x + 2y + z
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    lines = [f"v {x} {y} {z}" for x, y, z in v]
    for a, b, c, d in quads:
        lines += [f"f {a + 1} {b + 1} {c + 1}", f"f {a + 1} {c + 1} {d + 1}"]
    path.write_text("\n".join(lines) + "\n")


def write_cabinet(folder: Path) -> Path:
    """Write the synthetic cabinet (PartNet-Mobility format) into ``folder``.

    Hierarchy (node id: name [meshes]): 0 cabinet -> 1 body [body], 2 door -> (3 panel [door],
    4 handle [handle]), 5 drawer [drawer_front, drawer_box], 6 knob [knob], 7 base [base].
    Links: 0 hinge door (parts [2], inner node; axis x=0, z=0.51 along (0, 2, 0): not unit),
    1 slider drawer (+z), 2 hinge knob on the door (axis through its centre along z),
    3 heavy body (root), 4 static base (parent 3).
    Expected fine types: door->body R_V_S, drawer->body P_H, knob->door R_H_C, body<->base
    Fixed, knob->body None (the knob hangs on the door).
    """
    import json

    folder.mkdir(parents=True, exist_ok=True)
    (folder / "textured_objs").mkdir(exist_ok=True)
    for name, (lo, hi) in CABINET_BOXES.items():
        write_box_obj(folder / "textured_objs" / f"{name}.obj", lo, hi)

    def leaf(i, name, objs):
        return {"id": i, "name": name, "text": name, "objs": objs}

    tree = [{"id": 0, "name": "cabinet", "text": "Cabinet", "children": [
        leaf(1, "body", ["body"]),
        {"id": 2, "name": "door", "text": "door", "children": [
            leaf(3, "panel", ["door"]), leaf(4, "handle", ["handle"])]},
        leaf(5, "drawer", ["drawer_front", "drawer_box"]),
        leaf(6, "knob", ["knob"]),
        leaf(7, "base", ["base"]),
    ]}]
    lim = {"a": 0, "b": 90, "noLimit": False}
    links = [
        {"id": 0, "parent": 3, "joint": "hinge", "name": "door", "parts": [{"id": 2}],
         "jointData": {"axis": {"origin": [0, 0.3, 0.51], "direction": [0, 2, 0]}, "limit": lim}},
        {"id": 1, "parent": 3, "joint": "slider", "name": "drawer", "parts": [{"id": 5}],
         "jointData": {"axis": {"origin": [0, 0, 0], "direction": [0, 0, 1]},
                       "limit": {"a": 0, "b": 0.3, "noLimit": False, "rotates": False}}},
        {"id": 2, "parent": 0, "joint": "hinge", "name": "knob", "parts": [{"id": 6}],
         "jointData": {"axis": {"origin": [0.25, 0.65, 0.6], "direction": [0, 0, -1]},
                       "limit": {"a": 0, "b": 0, "noLimit": True}}},
        {"id": 3, "parent": -1, "joint": "heavy", "name": "body", "parts": [{"id": 1}],
         "jointData": {}},
        {"id": 4, "parent": 3, "joint": "static", "name": "base", "parts": [{"id": 7}],
         "jointData": {}},
    ]
    (folder / "result.json").write_text(json.dumps(tree))
    (folder / "mobility_v2.json").write_text(json.dumps(links))
    (folder / "meta.json").write_text(json.dumps({"model_cat": "StorageFurniture"}))
    return folder


@pytest.fixture
def cabinet(tmp_path: Path) -> Path:
    """A fresh synthetic cabinet folder (see :func:`write_cabinet`)."""
    return write_cabinet(tmp_path / "cabinet")


@pytest.fixture(scope="session")
def chromium() -> str:
    """Path of a headless Chromium (:func:`browser.find_browser`).

    None installed: the test is skipped, or fails under ``KINMO_REQUIRE_BROWSER=1`` /
    ``KINMO_REQUIRE_DATA=1`` (the README says how to install one).
    """
    from browser import BROWSERS, find_browser

    exe = find_browser()
    if exe is None:
        why = (f"no Chromium on PATH (looked for {', '.join(BROWSERS)}): install one, see the "
               "README's tests")
        if browser_required():
            pytest.fail(why)
        pytest.skip(why)
    return exe


@pytest.fixture(scope="session")
def tiny_gnn(tmp_path_factory) -> dict[str, Path]:
    """Two synthetic cabinets (``data``), their part graphs (``cache``) and a tiny motion GNN
    trained on them (``run``, the ``tiny`` preset shrunk further: the code under test is not
    the network's accuracy)."""
    from kinmo.data.build import build_graph
    from kinmo.data.readers import read_shape
    from kinmo.train.config import preset
    from kinmo.train.gnn import train_gnn
    from kinmo.train.split import Split

    root = tmp_path_factory.mktemp("tiny_gnn")
    ids = ["c1", "c2"]
    (root / "cache").mkdir()
    for oid in ids:
        write_cabinet(root / "data" / oid)
        build_graph(read_shape(root / "data" / oid), n_points=32).save(root / "cache" / f"{oid}.npz")
    cfg = preset("tiny", n_points=32, threads=1, epochs=1, batch_size=2)
    cfg = cfg.model_copy(update={"model": cfg.model.model_copy(update=dict(
        point_widths=[8], geo_dim=8, node_dim=8, edge_dim=8, semantic_dim=2, gnn_layers=1))})
    train_gnn(root / "cache", root / "run", cfg, split=Split(ids, []), progress=False)
    return {"root": root, "data": root / "data", "cache": root / "cache", "run": root / "run"}


def write_untrained_models(root: Path, gnn: str = "gnn") -> tuple[Path, Path]:
    """An untrained motion-GNN run (``root/<gnn>/model.pt``, the quick preset) and a small
    axis-network run (``root/axis/model.pt``), saved by the project's own savers (seeded)."""
    import torch

    from kinmo.features import SemanticVocab
    from kinmo.models.motion_gnn import MotionGNN
    from kinmo.refine.axis_net import AxisNetConfig, AxisSelectionNet
    from kinmo.refine.train import save_axis_model
    from kinmo.train.config import preset
    from kinmo.train.gnn import save_checkpoint

    torch.manual_seed(0)
    cfg = preset("quick")
    save_checkpoint(root / gnn / "model.pt", MotionGNN(cfg.model), cfg, SemanticVocab(), None, 0)
    net = AxisSelectionNet(AxisNetConfig(n_points=64, k=8, widths=[8, 8, 16], emb_dim=16,
                                         head=[16], dropout=0.0))
    save_axis_model(root / "axis" / "model.pt", net)
    return root / gnn, root / "axis"
