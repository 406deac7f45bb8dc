"""Helpers shared by the tests of the per-shape maps (:mod:`kinmo.parallel`, :mod:`kinmo.executor`)."""

from __future__ import annotations

from typing import Any, Callable


def collect(map_fn: Callable[..., bool], fn: Callable, items: list, workers: int,
            **kw: Any) -> tuple[bool, dict, dict]:
    """Run ``map_fn(fn, items, workers, on_result, on_error, **kw)`` and gather what it hands over.

    Returns ``(stopped, results, errors)``: ``results`` maps every item to its result (an item
    handed over twice fails the test), ``errors`` maps failed items to their exception, and a
    failed item's result is ``"failed"`` (the ``on_error`` value).
    """
    results: dict = {}
    errors: dict = {}

    def on_result(item, result):
        assert item not in results
        results[item] = result

    def on_error(item, e):
        errors[item] = e
        return "failed"

    stopped = map_fn(fn, items, workers, on_result, on_error, **kw)
    return stopped, results, errors
