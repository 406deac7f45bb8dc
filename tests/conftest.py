"""Shared fixtures.

The real objects live in ``../shared/data`` next to the checkout (or ``$KINMO_DATA``). Tests
that need them fail, never skip, when they are absent: CI always has them.
"""

from __future__ import annotations

import os
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
