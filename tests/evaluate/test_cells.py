"""Table cells of the evaluation (kinmo.evaluate.cells): missing figures as an en dash."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from kinmo.evaluate.cells import cell


@pytest.mark.parametrize("missing", [None, float("nan"), np.float64("nan"), np.float32("nan")])
def test_a_mean_over_nothing_is_a_dash_without_its_unit(missing):
    assert cell(missing) == "–"
    assert cell(missing, 1, "°") == "–"


@given(st.floats(allow_nan=False, allow_infinity=False, min_value=-1e6, max_value=1e6),
       st.integers(0, 6))
def test_a_number_keeps_python_formatting(v, places):
    assert cell(v, places) == f"{v:.{places}f}"
    assert cell(v, places, "°") == f"{v:.{places}f}°"


def test_integers_and_numpy_scalars_are_numbers():
    assert cell(3) == "3.00"
    assert cell(np.float32(0.5), 1) == "0.5"
    assert not math.isnan(float(cell(np.float64(0.25), 3)))


def test_negative_places_are_refused():
    with pytest.raises(ValueError, match="places"):
        cell(1.0, -1)
