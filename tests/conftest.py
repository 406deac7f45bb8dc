"""Shared fixtures.

The real objects live in ``../shared/data`` next to the checkout (or ``$KINMO_DATA``). Tests
that need them fail, never skip, when they are absent: CI always has them.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def data_root() -> Path:
    """The shared dataset folder (``$KINMO_DATA`` or ``<repo>/../shared/data``)."""
    return Path(os.environ.get("KINMO_DATA", REPO.parent / "shared" / "data"))


@pytest.fixture(scope="session")
def shared_data() -> Path:
    root = data_root()
    if not (root / "partnet-mobility").is_dir():
        raise FileNotFoundError(
            f"{root}: the shared dataset is missing (set KINMO_DATA to the folder holding "
            "partnet-mobility/ and partnet/)"
        )
    return root


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
    """Path of a headless Chromium (`browser.find_chromium`); fails when none."""
    from browser import find_chromium

    return find_chromium()


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
