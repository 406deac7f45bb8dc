"""mobility_v2.json / semantics.txt writers: format of the released files, round trip."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from kinmo.data.model import Joint, JointType, Link
from kinmo.data.readers import read_links, read_shape
from kinmo.data.writers import mobility_v2_dict, write_mobility_v2, write_semantics
from kinmo.errors import KinmoDataError

# refrigerator (hinge, a > b), cylindrical bottle, keyboard (116 links, sliders without the
# rotates keys, a free root with a placeholder axis), safe (junk/heavy links with axes), cart
# (unlimited hinges), laptop (non-unit and wrapped hinge limits)
OBJECTS = ["10849", "3574", "7619", "102278", "100496", "10040", "100162"]


def _normalised_original(raw: list[dict]) -> list[dict]:
    """What the writer must produce from a released file: the readers' normalisation applied
    (unit directions, sorted limits) and jointData {} for links without a moving joint."""
    out = []
    for lk in sorted(raw, key=lambda l: l["id"]):
        jd = {}
        if lk["joint"] in ("hinge", "slider"):
            ax, lim = lk["jointData"]["axis"], lk["jointData"]["limit"]
            d = np.asarray(ax["direction"], float)
            lo, hi = sorted((lim["a"], lim["b"]))
            limit = {"a": 0, "b": 0, "noLimit": True} if lim["noLimit"] else {
                "a": lo, "b": hi, "noLimit": False}
            if lk["joint"] == "slider":
                rot = bool(lim.get("rotates", False))
                no_rot = rot and bool(lim.get("noRotationLimit", False))
                limit.update(rotates=rot, noRotationLimit=no_rot,
                             rotationLimit=lim.get("rotationLimit", 0) if rot and not no_rot else 0)
            jd = {"axis": {"origin": ax["origin"], "direction": (d / np.linalg.norm(d)).tolist()},
                  "limit": limit}
        out.append({"id": lk["id"], "parent": lk["parent"], "joint": lk["joint"], "name": lk["name"],
                    "parts": [{"id": p["id"], "name": p["name"]} for p in lk["parts"]],
                    "jointData": jd})
    return out


def _close(a, b) -> bool:
    if isinstance(a, dict):
        return isinstance(b, dict) and list(a) == list(b) and all(_close(a[k], b[k]) for k in a)
    if isinstance(a, list):
        return isinstance(b, list) and len(a) == len(b) and all(_close(x, y) for x, y in zip(a, b))
    if isinstance(a, bool) or isinstance(b, bool) or isinstance(a, str):
        return a == b
    return abs(float(a) - float(b)) <= 1e-12 * max(1.0, abs(float(a)))


@pytest.mark.exactdata
@pytest.mark.parametrize("oid", OBJECTS)
def test_format_matches_released_file(mobility_root: Path, oid: str) -> None:
    shape = read_shape(mobility_root / oid)
    raw = json.loads((mobility_root / oid / "mobility_v2.json").read_text())
    written = mobility_v2_dict(shape.links, shape.hierarchy)
    expected = _normalised_original(raw)
    assert [l["id"] for l in written] == [l["id"] for l in expected]
    for w, e in zip(written, expected):
        assert _close(w, e), (oid, w, e)


@pytest.mark.exactdata
@pytest.mark.parametrize("oid", OBJECTS)
def test_round_trip_through_reader(mobility_root: Path, tmp_path: Path, oid: str) -> None:
    shape = read_shape(mobility_root / oid)
    path = write_mobility_v2(shape.links, tmp_path / "mobility_v2.json", shape.hierarchy)
    text = path.read_text()
    assert ", " not in text and ": " not in text  # compact, like the released files
    back = read_links(path, shape.hierarchy)
    assert len(back) == len(shape.links)
    for a, b in zip(sorted(shape.links, key=lambda l: l.id), back):
        assert (a.id, a.parent, a.name, a.parts) == (b.id, b.parent, b.name, b.parts)
        ja, jb = a.joint, b.joint
        assert (ja.type, ja.limit, ja.rotates, ja.rotation_limit) == (
            jb.type, jb.limit, jb.rotates, jb.rotation_limit)
        for u, v in ((ja.origin, jb.origin), (ja.direction, jb.direction)):
            assert (u is None) == (v is None)
            if u is not None:
                # exact up to the last bit (the reader re-normalises the unit direction)
                assert np.abs(u - v).max() <= 4e-16
    assert list(tmp_path.iterdir()) == [path]  # atomic write left no temporary file


@pytest.mark.exactdata
@pytest.mark.parametrize("oid", ["10849", "3574", "46108", "7619", "20453"])
def test_semantics_matches_released_file(mobility_root: Path, tmp_path: Path, oid: str) -> None:
    shape = read_shape(mobility_root / oid)
    original = (mobility_root / oid / "semantics.txt").read_text().split()
    labels = {int(original[i][5:]): original[i + 2] for i in range(0, len(original), 3)}
    path = write_semantics(shape.links, tmp_path / "semantics.txt", names=labels)
    assert path.read_text().split() == original
    # default labels: the link names
    write_semantics(shape.links, tmp_path / "s2.txt")
    lines = (tmp_path / "s2.txt").read_text().splitlines()
    assert [ln.split()[2] for ln in lines] == [l.name for l in sorted(shape.links, key=lambda l: l.id)]


@pytest.mark.exactdata
def test_generated_links_round_trip(tmp_path: Path, mobility_root: Path) -> None:
    """Links that never came from a file (e.g. predicted): non-unit input direction, open
    rotation limit, unlimited hinge."""
    shape = read_shape(mobility_root / "3574")
    body, lid = sorted(shape.links, key=lambda l: -l.id)  # body (1), lid (0)
    links = [
        body,
        Link(0, 1, "lid", lid.parts, Joint(JointType.SLIDER, np.array([0.1, 0.2, 0.3]),
                                           np.array([0.0, 2.0, 0.0]), (-0.5, 0.25), True, None)),
    ]
    path = write_mobility_v2(links, tmp_path / "m.json", shape.hierarchy)
    raw = json.loads(path.read_text())
    lim = raw[0]["jointData"]["limit"]
    assert lim == {"a": -0.5, "b": 0.25, "noLimit": False, "rotates": True,
                   "noRotationLimit": True, "rotationLimit": 0}
    back = read_links(path, shape.hierarchy)
    assert back[0].joint.rotates and back[0].joint.rotation_limit is None
    assert back[1].joint.type is JointType.FREE and raw[1]["jointData"] == {}
    hinge = Link(0, 1, "lid", lid.parts, Joint(JointType.HINGE, np.zeros(3), np.array([1.0, 0, 0])))
    raw = mobility_v2_dict([body, hinge])
    assert raw[0]["jointData"]["limit"] == {"a": 0, "b": 0, "noLimit": True}
    assert raw[0]["parts"] == [{"id": p, "name": ""} for p in lid.parts]  # no hierarchy given


def test_bad_links_raise(tmp_path: Path) -> None:
    no_axis = Link(0, -1, "x", (), Joint(JointType.HINGE))
    with pytest.raises(KinmoDataError, match="without an axis"):
        write_mobility_v2([no_axis], tmp_path / "m.json")
    orphan = Link(0, 5, "x", (), Joint(JointType.STATIC))
    with pytest.raises(KinmoDataError, match="parent 5"):
        write_mobility_v2([orphan], tmp_path / "m.json")
    with pytest.raises(KinmoDataError, match="whitespace"):
        write_semantics([Link(0, -1, "two words", (), Joint(JointType.FREE))], tmp_path / "s.txt")
    assert not list(tmp_path.iterdir())
