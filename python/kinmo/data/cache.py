"""Reading a part-graph cache written by ``kinmo prepare`` (issue 21 finding 3, issue 22).

A cache folder holds ``<key>.npz`` part graphs (:class:`~kinmo.data.graph.PartGraph`) and a
manifest (``manifest.csv`` + ``manifest.json``, :mod:`kinmo.prepare`) with one row per
shape: its key (``id``), source folder and source fingerprint
(:func:`kinmo.stages.source_fingerprint`). Every graph records the same key and fingerprint
in its ``meta`` (``meta["key"]``, ``meta["fingerprint"]``).

Readers trust nothing on disk blindly:

- :func:`check_manifest`: the manifest accounts for the whole run (an interrupted
  ``kinmo prepare`` is refused).
- :func:`check_entry`: a graph is the one its manifest row names (same key, same source
  fingerprint): an ``.npz`` copied over another shape's is caught.
- :func:`load_cache` (``train``, ``eval``): every entry checked, one error line otherwise.
- :func:`cached_graph` (``predict --cache``): an entry whose source folder changed since
  ``prepare`` (e.g. ``result.json`` edited) or that does not match its row is rebuilt from
  the source when it is present, and refused (one line naming the shape) when it is not.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Sequence
from pathlib import Path

from kinmo.data.graph import PartGraph
from kinmo.errors import KinmoDataError
from kinmo.prepare import ManifestRow, read_manifest
from kinmo.stages import source_fingerprint

__all__ = ["cached_graph", "check_entry", "check_manifest", "load_cache", "manifest_rows"]

logger = logging.getLogger(__name__)


def check_manifest(cache: str | Path) -> list[ManifestRow]:
    """The rows of a cache folder's manifest, after checking that it accounts for the run.

    ``manifest.json`` records whether the run that wrote it finished (``complete``; a run
    writes ``complete: false`` before its first shape). A run killed or stopped early
    (``--strict``) leaves it false, maybe with graphs on disk that no row lists; reading
    such a cache would silently use part of the data, so it is refused, saying how many
    shapes are missing and how to resume.

    Parameters
    ----------
    cache : str or Path
        A cache folder written by :func:`kinmo.prepare.prepare_dataset` (holding
        ``manifest.csv``).

    Returns
    -------
    list of ManifestRow

    Raises
    ------
    KinmoDataError
        The manifest is missing or malformed, or incomplete: ``"<cache>: incomplete cache:
        the manifest accounts for K of N shapes (M graphs on disk not in it); ... resume it
        with `kinmo prepare <root> --out <cache>`"``.
    """
    cache = Path(cache)
    rows = read_manifest(cache)
    info_path = cache / "manifest.json"
    if not info_path.is_file():  # a manifest.csv alone (hand-made or older): trust it
        return rows
    try:
        info = json.loads(info_path.read_text(encoding="utf-8"))
        complete, n_shapes = bool(info["complete"]), int(info["n_shapes"])
        root = str(info.get("root", "DIR"))
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise KinmoDataError(info_path, f"malformed manifest: {e}") from None
    if complete:
        return rows
    listed = {r.id for r in rows}
    extra = sum(p.stem not in listed for p in cache.glob("*.npz"))
    raise KinmoDataError(
        cache,
        f"incomplete cache: the manifest accounts for {len(rows)} of {n_shapes} shapes "
        f"({n_shapes - len(rows)} missing, {extra} graphs on disk not in it): `kinmo prepare` "
        f"was interrupted or stopped early; resume it with `kinmo prepare {root} --out {cache}`",
    )


def manifest_rows(cache: str | Path) -> dict[str, ManifestRow] | None:
    """``id -> row`` of a cache's checked manifest (:func:`check_manifest`), or None when
    the folder has no ``manifest.csv`` (a hand-made cache: entries cannot be checked)."""
    cache = Path(cache)
    if not (cache / "manifest.csv").is_file():
        return None
    return {r.id: r for r in check_manifest(cache)}


def entry_problem(graph: PartGraph, key: str, row: ManifestRow | None) -> str:
    """Why ``graph`` (read from ``<key>.npz``) is not the entry its manifest row names, or
    ``""`` when it is (or cannot be told: no row, or a graph written before keys were
    recorded)."""
    meta_key = graph.meta.get("key")
    if meta_key is not None and str(meta_key) != key:
        return f"holds the part graph of shape {str(meta_key)!r}, not {key!r} (copied over?)"
    if row is None:
        return ""
    if row.status not in ("ok", "skipped"):
        return f"the manifest lists shape {key!r} as {row.status}"
    fp = graph.meta.get("fingerprint")
    if row.fingerprint and fp is not None and str(fp) != row.fingerprint:
        return (f"its source fingerprint {fp} is not the manifest's {row.fingerprint} for "
                f"shape {key!r} (replaced after `kinmo prepare`?)")
    return ""


def check_entry(graph: PartGraph, path: str | Path, row: ManifestRow | None) -> PartGraph:
    """Check that ``graph``, read from ``path`` (``<key>.npz``), is the entry ``row`` names.

    Returns
    -------
    PartGraph
        ``graph`` itself.

    Raises
    ------
    KinmoDataError
        ``"<path>: stale cache entry: ...; rebuild it with `kinmo prepare`"``: the graph
        records another key (an ``.npz`` copied over another shape's) or another source
        fingerprint than its manifest row.
    """
    path = Path(path)
    problem = entry_problem(graph, path.stem, row)
    if problem:
        raise KinmoDataError(path, f"stale cache entry: {problem}; rebuild it with `kinmo prepare`")
    return graph


def load_cache(cache: str | Path, ids: Sequence[str] | None = None) -> list[PartGraph]:
    """Read the part graphs of a cache folder written by ``kinmo prepare``.

    Parameters
    ----------
    cache : str or Path
        Folder with ``<id>.npz`` files and (normally) ``manifest.csv``. With a manifest only
        its ``ok``/``skipped`` rows are read, an incomplete manifest (an interrupted
        ``kinmo prepare``) is refused (:func:`check_manifest`), and every graph must be the
        entry its row names (:func:`check_entry`); without one every ``*.npz``. Every graph
        is checked (:meth:`PartGraph.load`).
    ids : sequence of str, optional
        Read only these ids (in this order).

    Returns
    -------
    list of PartGraph
        Sorted by id unless ``ids`` is given.

    Raises
    ------
    KinmoDataError
        The folder does not exist, holds no graphs, its manifest is incomplete, a requested
        id is missing, a graph is corrupt, or a graph is not the entry its manifest row
        names (each naming the file).
    """
    cache = Path(cache)
    if not cache.is_dir():
        raise KinmoDataError(cache, "cache folder does not exist (run `kinmo prepare`)")
    rows = manifest_rows(cache)
    if ids is None:
        if rows is not None:
            keys = sorted(k for k, r in rows.items() if r.status in ("ok", "skipped"))
        else:
            keys = sorted(p.stem for p in cache.glob("*.npz"))
        if not keys:
            raise KinmoDataError(cache, "no part graphs in the cache (run `kinmo prepare`)")
    else:
        keys = [str(i) for i in ids]
    out = []
    for k in keys:
        p = cache / f"{k}.npz"
        if not p.is_file():
            raise KinmoDataError(p, "part graph is missing from the cache")
        out.append(check_entry(PartGraph.load(p), p, None if rows is None else rows.get(k)))
    return out


def cached_graph(cache: str | Path, key: str, source: str | Path | None,
                 rows: dict[str, ManifestRow] | None = None) -> PartGraph | None:
    """The cached graph of shape ``key`` when it is current, else None (rebuild it).

    Parameters
    ----------
    cache : str or Path
        A ``kinmo prepare`` cache folder.
    key : str
        The shape's cache key (:func:`kinmo.stages.cache_key`).
    source : str or Path or None
        The shape folder the entry was built from, when the caller has it.
    rows : dict, optional
        :func:`manifest_rows` of ``cache``, read once by a caller looping over shapes.

    Returns
    -------
    PartGraph or None
        The graph when ``<key>.npz`` exists, is intact, is the entry its manifest row names
        and (with a source) records the source's current fingerprint; None when there is no
        entry, or when it is stale and the source is present (the caller builds the graph
        from the source; a log line says why).

    Raises
    ------
    KinmoDataError
        The entry is corrupt (:meth:`PartGraph.load`, naming the file), or stale while the
        source is absent: one line naming the shape.
    """
    p = Path(cache) / f"{key}.npz"
    if not p.is_file():
        return None
    if rows is None:
        rows = manifest_rows(cache)
    has_source = source is not None and Path(source).is_dir()
    graph = PartGraph.load(p)  # a corrupt file is named, as every reader does
    problem = entry_problem(graph, key, None if rows is None else rows.get(key))
    if not problem and has_source:
        fp, now = graph.meta.get("fingerprint"), source_fingerprint(source)  # type: ignore[arg-type]
        if fp is not None and str(fp) != now:
            problem = f"its source {source} changed since `kinmo prepare`"
    if not problem:
        return graph
    if has_source:
        logger.warning("%s: stale cache entry of shape %r (%s): rebuilt from the source", p, key, problem)
        return None
    raise KinmoDataError(p, f"stale cache entry of shape {key!r}: {problem}, and its source is "
                            "absent; rebuild it with `kinmo prepare`")
