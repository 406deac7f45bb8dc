"""Stale caches caught (issue 21 finding 3): a cache entry is the one its manifest row names,
and ``predict --cache`` never trusts an entry whose source changed after ``kinmo prepare``."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest
from conftest import write_cabinet

from kinmo.data.cache import cached_graph, check_manifest, load_cache, manifest_rows
from kinmo.errors import KinmoDataError
from kinmo.predict import _graph_for
from kinmo.prepare import PrepareConfig, prepare_dataset
from kinmo.data.readers import read_shape

CFG = PrepareConfig(n_points=32)


@pytest.fixture
def cabinets(tmp_path: Path) -> tuple[Path, Path]:
    """Two cabinets, ``s2`` without its knob (fewer parts), prepared into a cache."""
    root = tmp_path / "data"
    write_cabinet(root / "s1")
    write_cabinet(root / "s2")
    _drop_knob(root / "s2")
    out = tmp_path / "cache"
    assert prepare_dataset(root, out, CFG, workers=1, progress=False).ok
    return root, out


def _drop_knob(folder: Path) -> None:
    res = folder / "result.json"
    tree = json.loads(res.read_text())
    tree[0]["children"] = [c for c in tree[0]["children"] if c["name"] != "knob"]
    res.write_text(json.dumps(tree))
    mob = folder / "mobility_v2.json"
    links = json.loads(mob.read_text())
    links = [ln for ln in links if all(p["id"] != 6 for p in ln["parts"])]
    mob.write_text(json.dumps(links))


def test_an_npz_copied_over_another_shapes_is_refused_by_readers(cabinets) -> None:
    root, out = cabinets
    shutil.copyfile(out / "s1.npz", out / "s2.npz")
    with pytest.raises(KinmoDataError) as e:
        load_cache(out)
    msg = str(e.value)
    assert msg.startswith(str(out / "s2.npz")) and "stale cache entry" in msg and "'s1'" in msg
    assert "\n" not in msg


def test_an_entry_replaced_by_another_fingerprint_is_refused(cabinets) -> None:
    root, out = cabinets
    # a foreign s2 prepared from another source (same key, other fingerprint)
    other = root.parent / "other" / "s2"
    write_cabinet(other)
    prepare_dataset(other.parent, root.parent / "cache2", CFG, workers=1, progress=False)
    shutil.copyfile(root.parent / "cache2" / "s2.npz", out / "s2.npz")
    with pytest.raises(KinmoDataError, match=re.escape("fingerprint")):
        load_cache(out)


def test_predict_cache_rebuilds_an_npz_copied_over_another_shapes(cabinets) -> None:
    root, out = cabinets
    want = len(load_cache(out, ["s2"])[0].node_ids)
    shutil.copyfile(out / "s1.npz", out / "s2.npz")
    g = _graph_for(root / "s2", root, read_shape(root / "s2"), out, manifest_rows(out))
    assert len(g.node_ids) == want < len(load_cache(out, ["s1"])[0].node_ids)


def test_predict_cache_rebuilds_after_result_json_is_edited(cabinets) -> None:
    root, out = cabinets
    before = len(load_cache(out, ["s1"])[0].node_ids)
    _drop_knob(root / "s1")
    g = _graph_for(root / "s1", root, read_shape(root / "s1"), out, manifest_rows(out))
    assert len(g.node_ids) == before - 1
    # an intact, current entry is read from the cache as it is
    g2 = cached_graph(out, "s2", root / "s2")
    assert g2 is not None and g2.meta["key"] == "s2"


def test_a_stale_entry_without_its_source_is_refused_naming_the_shape(cabinets) -> None:
    root, out = cabinets
    shutil.copyfile(out / "s1.npz", out / "s2.npz")
    with pytest.raises(KinmoDataError) as e:
        cached_graph(out, "s2", root / "gone")
    assert "'s2'" in str(e.value) and "source is absent" in str(e.value)
    assert "\n" not in str(e.value)


def test_check_manifest_lives_on_the_data_side(cabinets) -> None:
    _, out = cabinets
    assert sorted(r.id for r in check_manifest(out)) == ["s1", "s2"]
