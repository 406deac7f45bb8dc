"""The learned range prior (kinmo.ranges.prior, issue 35)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from motion_cabinet import cabinet_graph

from kinmo.errors import KinmoDataError
from kinmo.ranges import RangeEntry, RangePrior, fit_range_prior, true_ranges


def _with_limits(g, door, drawer, door_dir=(0.0, 1.0, 0.0)):
    links = [dict(lk) for lk in g.meta["links"]]
    links[1]["limit"], links[1]["direction"] = door, list(door_dir)
    links[2]["limit"] = drawer
    g.meta = {**g.meta, "links": links}
    return g


def test_true_ranges_in_the_opening_sign_convention():
    # the door (hinge at its left edge, x = -w/2) swings out of the front (+z) by a negative
    # turn about +y: in the tree's convention (axis -y) that is a positive range
    g = _with_limits(cabinet_graph(seed=0), [-90.0, 0.0], [0.0, 0.4])
    door, drawer = true_ranges(g)
    assert (door.kind, door.name, door.continuous) == ("hinge", "door", False)
    assert (door.lo, door.hi) == pytest.approx((0.0, 90.0))
    # the same motion annotated about -y
    g2 = _with_limits(cabinet_graph(seed=0), [0.0, 90.0], [0.0, 0.4], door_dir=(0.0, -1.0, 0.0))
    assert (true_ranges(g2)[0].lo, true_ranges(g2)[0].hi) == pytest.approx((0.0, 90.0))
    # the opposite motion (into the body) stays negative
    g3 = _with_limits(cabinet_graph(seed=0), [0.0, 90.0], [0.0, 0.4])
    assert (true_ranges(g3)[0].lo, true_ranges(g3)[0].hi) == pytest.approx((-90.0, 0.0))
    # slider travel in units of the drawer's extent along its axis (its depth, 0.06)
    ext = np.ptp(g.points[[4, 5]].reshape(-1, 3) @ np.array([0.0, 0.0, 1.0]))
    assert drawer.kind == "slider" and drawer.hi == pytest.approx(0.4 / max(ext, 0.02 * g.scale))


def test_continuous_hinges():
    g = _with_limits(cabinet_graph(seed=0), None, [0.0, 0.4])
    assert true_ranges(g)[0].continuous
    g = _with_limits(cabinet_graph(seed=0), [-180.0, 180.0], [0.0, 0.4])  # a full turn
    assert true_ranges(g)[0].continuous


def test_fit_takes_the_medoid_and_the_most_specific_group():
    gs = [_with_limits(cabinet_graph(seed=s, jitter=0.1), lim, [0.0, 0.4])
          for s, lim in enumerate(([-90.0, 0.0], [-95.0, 0.0], [-180.0, 0.0]))]
    prior = fit_range_prior(gs)
    e = prior.lookup("hinge", "StorageFurniture", "door")
    assert (e.category, e.name, e.n) == ("StorageFurniture", "door", 3)
    assert (e.lo, e.hi) == (0.0, 95.0)  # overlaps the others most: an actual range, not a mean
    assert prior.lookup("hinge", "Laptop", "door").category is None  # by name
    assert prior.lookup("hinge", "Laptop", "lid").name is None  # the kind alone
    assert prior.lookup("hinge", "storagefurniture", "DOOR") is e  # case-insensitive
    assert RangePrior().lookup("hinge", "StorageFurniture", "door") is None


def test_a_training_range_without_the_rest_state_is_widened_to_it():
    # a door annotated 70 to 178 degrees (a washing machine of the shared data) and two
    # ranges from rest: the group's range holds 0, whichever is the medoid
    gs = [_with_limits(cabinet_graph(seed=s, jitter=0.1), lim, [0.1, 0.9])
          for s, lim in enumerate(([-178.0, -70.0], [-178.0, -70.0], [-90.0, 0.0]))]
    assert (true_ranges(gs[0])[0].lo, true_ranges(gs[0])[0].hi) == pytest.approx((70.0, 178.0))
    prior = fit_range_prior(gs)
    door = prior.lookup("hinge", "StorageFurniture", "door")
    assert (door.lo, door.hi) == pytest.approx((0.0, 178.0))
    drawer = prior.lookup("slider", "StorageFurniture", "drawer")
    assert drawer.lo == 0.0 and drawer.hi > 0.0


def test_hinges_are_also_grouped_by_fine_type_for_continuity():
    """The kind-alone group takes its continuity from the fine type's group (module
    docstring); more specific groups ignore the fine type."""
    from kinmo.data.model import FINE_TYPES

    g = _with_limits(cabinet_graph(seed=0), None, [0.0, 0.4])  # the door turns freely
    fine = true_ranges(g)[0].fine
    assert fine in FINE_TYPES and fine.startswith("R_")
    prior = fit_range_prior([g, _with_limits(cabinet_graph(seed=1, jitter=0.1), [-90.0, 0.0], [0.0, 0.4])])
    group = [e for e in prior.entries if e.fine]
    assert [(e.kind, e.category, e.name, e.fine, e.n, e.continuous) for e in group] == \
           [("hinge", None, None, fine, 2, 0.5)]
    prior = RangePrior([RangeEntry("hinge", None, None, 10, 0.2, 0.0, 100.0),
                        RangeEntry("hinge", "Oven", None, 4, 0.0, 0.0, 90.0),
                        RangeEntry("hinge", None, None, 6, 0.9, -30.0, 30.0, "R_H_C")])
    knob = prior.lookup("hinge", "Mixer", "part_3", "R_H_C")
    assert (knob.continuous, knob.lo, knob.hi, knob.fine) == (0.9, 0.0, 100.0, None) and knob.is_continuous
    assert prior.lookup("hinge", None, None, "R_V_S").continuous == 0.2  # no group of that type
    assert prior.lookup("hinge", None, None).continuous == 0.2
    assert prior.lookup("hinge", "Oven", "knob", "R_H_C").continuous == 0.0  # the category's group
    assert prior.lookup("slider", None, None, "R_H_C") is None


def test_save_load_round_trip(tmp_path):
    prior = fit_range_prior([cabinet_graph(seed=0)])
    assert any(e.fine for e in prior.entries)
    prior.save(tmp_path / "ranges.json")
    again = RangePrior.load(tmp_path / "ranges.json")
    assert again.entries == prior.entries and again.min_extent == prior.min_extent
    # a version 1 file (no fine-type groups) still loads
    doc = json.loads((tmp_path / "ranges.json").read_text())
    doc = {**doc, "version": 1, "entries": [e for e in doc["entries"] if "fine" not in e]}
    (tmp_path / "ranges.json").write_text(json.dumps(doc))
    assert RangePrior.load(tmp_path / "ranges.json").entries == [e for e in prior.entries if not e.fine]


def test_the_slider_unit_floor_is_stored_with_the_prior(tmp_path):
    """A button thinner than the floor: its travel is learned per floor, so the floor is
    part of the prior; a file written before it was stored used the legacy 2 %."""
    from kinmo.ranges.prior import LEGACY_MIN_EXTENT_FRACTION, MIN_EXTENT_FRACTION, axial_extent

    g = _with_limits(cabinet_graph(seed=0), [0.0, 90.0], [0.0, 0.004])
    thin = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.003 * g.scale]])
    assert axial_extent(thin, np.array([0.0, 0.0, 1.0]), g.scale) == pytest.approx(0.003 * g.scale)
    assert axial_extent(thin, np.array([0.0, 0.0, 1.0]), g.scale, 0.02) == pytest.approx(0.02 * g.scale)
    new, old = fit_range_prior([g]), fit_range_prior([g], LEGACY_MIN_EXTENT_FRACTION)
    assert (new.min_extent, old.min_extent) == (MIN_EXTENT_FRACTION, LEGACY_MIN_EXTENT_FRACTION)
    f = tmp_path / "ranges.json"
    old.save(f)
    doc = json.loads(f.read_text())
    assert doc["min_extent"] == LEGACY_MIN_EXTENT_FRACTION
    del doc["min_extent"]  # as written before session 16
    f.write_text(json.dumps(doc))
    assert RangePrior.load(f).min_extent == LEGACY_MIN_EXTENT_FRACTION
    for bad in (0, -0.1, 2.0, "0.02", True):
        f.write_text(json.dumps({**doc, "min_extent": bad}))
        with pytest.raises(KinmoDataError, match="min_extent") as e:
            RangePrior.load(f)
        assert "\n" not in str(e.value)


@pytest.mark.parametrize("entry, why", [
    ({"kind": "hinge", "n": 1, "continuous": 0.0, "lo": 10.0, "hi": 0.0}, "lo <= hi"),
    ({"kind": "hinge", "n": 1, "continuous": 0.0, "lo": float("nan"), "hi": 1.0}, "finite"),
    ({"kind": "hinge", "n": 1, "continuous": 0.0, "lo": 0.0, "hi": 1e9}, "finite"),
    ({"kind": "screw", "n": 1, "continuous": 0.0, "lo": 0.0, "hi": 1.0}, "kind"),
    ({"kind": "hinge", "n": 0, "continuous": 0.0, "lo": 0.0, "hi": 1.0}, "positive"),
    ({"kind": "hinge", "n": 1, "continuous": 2.0, "lo": 0.0, "hi": 1.0}, "share"),
    ({"kind": "hinge", "n": 1, "continuous": 0.0, "lo": 0.0, "hi": None}, "both"),
    ({"kind": "hinge", "n": 1, "continuous": 0.0, "lo": 0.0, "hi": 1.0, "name": ["a"]}, "string"),
    ({"kind": "hinge", "n": 1, "continuous": 0.0, "lo": 0.0, "hi": 1.0, "fine": "R_X"}, "fine motion type"),
    ({"kind": "hinge", "n": 1, "continuous": 0.0, "lo": 0.0, "hi": 1.0, "fine": "R_H_C", "name": "knob"},
     "without category and name"),
])
def test_malformed_files_get_one_clear_line(tmp_path, entry, why):
    f = tmp_path / "ranges.json"
    f.write_text(json.dumps({"format": "kinmo-range-prior", "version": 1, "entries": [entry]},
                            allow_nan=True))
    with pytest.raises(KinmoDataError, match=why) as e:
        RangePrior.load(f)
    assert "ranges.json" in str(e.value) and "\n" not in str(e.value)


def test_entry_count_is_bounded_by_its_own_limit(tmp_path, monkeypatch):
    entry = {"kind": "hinge", "n": 1, "continuous": 0.0, "lo": 0.0, "hi": 90.0}
    f = tmp_path / "ranges.json"
    f.write_text(json.dumps({"format": "kinmo-range-prior", "version": 1, "entries": [entry] * 3}))
    assert len(RangePrior.load(f).entries) == 3
    monkeypatch.setenv("KINMO_MAX_RANGE_ENTRIES", "2")
    with pytest.raises(KinmoDataError, match="3 entries per range prior exceeds the limit of 2") as e:
        RangePrior.load(f)
    assert "\n" not in str(e.value)
    monkeypatch.setenv("KINMO_MAX_PARTS", "2")  # the parts limit is not this one
    monkeypatch.delenv("KINMO_MAX_RANGE_ENTRIES")
    assert len(RangePrior.load(f).entries) == 3


def test_other_formats_and_newer_versions_are_refused(tmp_path):
    f = tmp_path / "ranges.json"
    f.write_text(json.dumps({"format": "something-else", "version": 1, "entries": []}))
    with pytest.raises(KinmoDataError, match="not a range prior"):
        RangePrior.load(f)
    f.write_text(json.dumps({"format": "kinmo-range-prior", "version": 99, "entries": []}))
    with pytest.raises(KinmoDataError, match="not supported"):
        RangePrior.load(f)
    with pytest.raises(KinmoDataError, match="missing"):
        RangePrior.load(tmp_path / "absent.json")


def test_entry_continuity():
    assert RangeEntry("hinge", None, None, 4, 0.75, 0.0, 90.0).is_continuous
    assert RangeEntry("hinge", None, None, 4, 1.0, None, None).is_continuous
    assert not RangeEntry("hinge", None, None, 4, 0.25, 0.0, 90.0).is_continuous
