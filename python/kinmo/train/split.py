"""Deterministic, category-stratified train/test splits of a dataset.

Each category's objects are shuffled with a seeded generator and ``round(n * fraction)``
of them go to the test set, at least one and at most ``n - 1`` when the category has two or
more objects (so both sets see it); a category with a single object goes to training. The
same ids, categories, fraction and seed always give the same split, independent of the input
order. Splits are saved as JSON (``RUN/split.json``)::

    {"seed": 0, "test_fraction": 0.25, "train": ["100028", ...], "test": [...],
     "categories": {"100028": "KitchenPot", ...}}
"""

from __future__ import annotations

import json
import random
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from kinmo.errors import KinmoDataError
from kinmo.io import write_json

__all__ = ["Split", "make_split"]


@dataclass
class Split:
    """A train/test split of shape ids.

    Attributes
    ----------
    train, test : list of str
        Sorted shape ids.
    categories : dict of str to str
        Category of every id.
    seed : int
    test_fraction : float
    """

    train: list[str]
    test: list[str]
    categories: dict[str, str] = field(default_factory=dict)
    seed: int = 0
    test_fraction: float = 0.25

    def save(self, path: str | Path) -> None:
        """Write the split as JSON, atomically."""
        write_json(path, {
            "seed": self.seed,
            "test_fraction": self.test_fraction,
            "train": self.train,
            "test": self.test,
            "categories": self.categories,
        })

    @classmethod
    def load(cls, path: str | Path) -> Split:
        """Read a split written by :meth:`save`.

        Raises
        ------
        KinmoDataError
            Missing or malformed file, or an id in both sets.
        """
        path = Path(path)
        try:
            d = json.loads(path.read_text())
            sp = cls(
                train=[str(x) for x in d["train"]],
                test=[str(x) for x in d["test"]],
                categories={str(k): str(v) for k, v in d.get("categories", {}).items()},
                seed=int(d.get("seed", 0)),
                test_fraction=float(d.get("test_fraction", 0.25)),
            )
        except OSError as e:
            raise KinmoDataError(path, f"cannot read split: {e.strerror or e}") from None
        except (ValueError, KeyError, TypeError) as e:
            raise KinmoDataError(path, f"malformed split file: {e}") from None
        both = set(sp.train) & set(sp.test)
        if both:
            raise KinmoDataError(path, f"ids in both train and test: {sorted(both)[:5]}")
        return sp


def make_split(
    ids: Sequence[str],
    categories: Sequence[str],
    test_fraction: float = 0.25,
    seed: int = 0,
) -> Split:
    """Split shape ids into train and test sets, stratified by category.

    Parameters
    ----------
    ids : sequence of str
        Shape ids (unique).
    categories : sequence of str
        Category of each id.
    test_fraction : float
        In ``[0, 1)``: share of each category held out (module docstring for the rounding).
    seed : int

    Returns
    -------
    Split

    Raises
    ------
    ValueError
        Lengths differ, duplicate ids, or ``test_fraction`` out of range.
    """
    ids = [str(i) for i in ids]
    cats = [str(c) for c in categories]
    if len(ids) != len(cats):
        raise ValueError(f"{len(ids)} ids but {len(cats)} categories")
    if len(set(ids)) != len(ids):
        raise ValueError("duplicate ids")
    if not 0.0 <= test_fraction < 1.0:
        raise ValueError(f"test_fraction must be in [0, 1), got {test_fraction}")
    by_cat: dict[str, list[str]] = {}
    for i, c in zip(ids, cats):
        by_cat.setdefault(c, []).append(i)
    train: list[str] = []
    test: list[str] = []
    for c in sorted(by_cat):
        members = sorted(by_cat[c])
        rng = random.Random(f"{seed}:{c}")
        rng.shuffle(members)
        n = len(members)
        k = int(round(n * test_fraction)) if test_fraction > 0 else 0
        if n >= 2 and test_fraction > 0:
            k = min(max(k, 1), n - 1)
        else:
            k = 0 if n < 2 else k
        test += members[:k]
        train += members[k:]
    return Split(sorted(train), sorted(test), dict(zip(ids, cats)), seed, test_fraction)
