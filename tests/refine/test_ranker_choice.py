"""How a ranker picks its winner (kinmo.refine.ranker: Ranker.choose, direction_choice)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from kinmo.errors import KinmoDataError
from kinmo.refine.features import FEATURES
from kinmo.refine.ranker import Ranker, direction_choice, load_ranker

# three lines of direction y (an OBB edge, the centre, an interaction line) share 0.6;
# one line of direction x holds 0.3, more than any single y line
P = np.array([0.2, 0.25, 0.15, 0.3, 0.1])
D = np.array([[0, 1, 0], [0, -1, 0.01], [0.02, 1, 0], [1, 0, 0], [0, 0, 1]], float)


def test_the_direction_of_most_mass_wins_then_its_likeliest_line():
    assert int(np.argmax(P)) == 3
    assert direction_choice(P, D) == 1  # y holds 0.6; its likeliest line is the second
    # lines more than the tolerance apart are other directions
    tilted = D.copy()
    tilted[1] = [0.0, 1.0, 0.2]  # 11 degrees off y
    assert direction_choice(P, tilted) == 0  # y: 0.2 + 0.15 = 0.35 > x: 0.3 > tilted: 0.25
    assert direction_choice(P, tilted, max_deg=15.0) == 1
    # one candidate; ties keep the first candidate's direction
    assert direction_choice(np.array([1.0]), np.array([[0.0, 0.0, 1.0]])) == 0
    assert direction_choice(np.array([0.5, 0.5]), np.eye(3)[:2]) == 0
    with pytest.raises(ValueError, match="directions"):
        direction_choice(P, D[:3])


def _ranker(choice: str) -> Ranker:
    n = len(FEATURES)
    return Ranker(FEATURES, np.zeros(n), np.zeros(n), np.ones(n), choice=choice)


def test_choose_follows_the_rankers_choice_and_survives_its_file(tmp_path):
    line, direction = _ranker("line"), _ranker("direction")
    assert line.choose(P, D) == 3
    assert direction.choose(P, D) == 1
    assert direction.choose(P) == 3  # without directions: the likeliest line
    back = load_ranker(direction.save(tmp_path / "d.json"))
    assert back.choice == "direction" and back.choose(P, D) == 1
    # files written before the choice hold no key and keep the likeliest line
    d = json.loads((tmp_path / "d.json").read_text())
    assert d.pop("choice") == "direction"
    (tmp_path / "old.json").write_text(json.dumps(d))
    assert load_ranker(tmp_path / "old.json").choice == "line"
    d["choice"] = "vote"
    (tmp_path / "bad.json").write_text(json.dumps(d))
    with pytest.raises(KinmoDataError, match="choice"):
        load_ranker(tmp_path / "bad.json")
