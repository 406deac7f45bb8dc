"""Fixtures shared by the inference tests."""

from __future__ import annotations

import pytest
from conftest import write_cabinet

from kinmo.data.build import build_graph
from kinmo.data.readers import read_shape


@pytest.fixture(scope="module")
def graph(tmp_path_factory):
    """The test cabinet (``conftest.write_cabinet``) as a part graph of 64 points per part."""
    d = tmp_path_factory.mktemp("cab") / "s1"
    write_cabinet(d)
    return build_graph(read_shape(d), n_points=64)
