"""Category-stratified train/test splits."""

from __future__ import annotations

import json

import pytest

from kinmo.errors import KinmoDataError
from kinmo.train.split import Split, make_split


def _data():
    cats = {"A": 6, "B": 2, "C": 1, "D": 4}
    ids, categories = [], []
    for c, n in cats.items():
        for k in range(n):
            ids.append(f"{c}{k}")
            categories.append(c)
    return ids, categories


def test_stratified_and_deterministic():
    ids, cats = _data()
    s = make_split(ids, cats, test_fraction=0.25, seed=0)
    assert sorted(s.train + s.test) == sorted(ids)
    assert not set(s.train) & set(s.test)
    by = {c: ([i for i in s.train if i[0] == c], [i for i in s.test if i[0] == c]) for c in "ABCD"}
    assert [len(by["A"][1]), len(by["B"][1]), len(by["C"][1]), len(by["D"][1])] == [2, 1, 0, 1]
    # every category with >= 2 objects is on both sides; a singleton trains
    for c in "ABD":
        assert by[c][0] and by[c][1]
    assert by["C"][0] == ["C0"]
    # same inputs in another order -> same split; another seed -> (here) another one
    s2 = make_split(ids[::-1], cats[::-1], 0.25, 0)
    assert (s2.train, s2.test) == (s.train, s.test)
    others = {tuple(make_split(ids, cats, 0.25, k).test) for k in range(1, 6)}
    assert len(others | {tuple(s.test)}) > 1


def test_validation():
    with pytest.raises(ValueError, match="categories"):
        make_split(["a", "b"], ["x"])
    with pytest.raises(ValueError, match="duplicate"):
        make_split(["a", "a"], ["x", "x"])
    with pytest.raises(ValueError, match="test_fraction"):
        make_split(["a"], ["x"], test_fraction=1.0)
    assert make_split(["a", "b"], ["x", "x"], test_fraction=0.0).test == []


def test_save_load_round_trip_and_bad_files(tmp_path):
    ids, cats = _data()
    s = make_split(ids, cats, seed=3)
    s.save(tmp_path / "split.json")
    back = Split.load(tmp_path / "split.json")
    assert (back.train, back.test, back.seed, back.categories) == (s.train, s.test, 3, s.categories)
    with pytest.raises(KinmoDataError, match="missing.json"):
        Split.load(tmp_path / "missing.json")
    (tmp_path / "bad.json").write_text(json.dumps({"train": ["a"], "test": ["a"]}))
    with pytest.raises(KinmoDataError, match="both"):
        Split.load(tmp_path / "bad.json")
    (tmp_path / "bad2.json").write_text("{not json")
    with pytest.raises(KinmoDataError, match="malformed"):
        Split.load(tmp_path / "bad2.json")
