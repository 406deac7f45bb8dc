"""PartNet-Mobility's own files as exporters: ``mobility_v2.json`` and ``semantics.txt``.

Thin registrations of :mod:`kinmo.data.writers` (format described there); lossless by
construction, they are kinmo's reference format.
"""

from __future__ import annotations

from pathlib import Path

from kinmo.data.writers import write_mobility_v2, write_semantics
from kinmo.export import ExportContext, register


@register("mobility_v2", "PartNet-Mobility mobility_v2.json (links, joints, axes, limits)")
def write_mobility(ctx: ExportContext) -> list[Path]:
    """Write ``mobility_v2.json`` (part names from the hierarchy)."""
    return [write_mobility_v2(ctx.links, ctx.out_dir / "mobility_v2.json", ctx.shape.hierarchy)]


@register("semantics", "PartNet-Mobility semantics.txt (link_<id> <joint> <name>)")
def write_semantics_txt(ctx: ExportContext) -> list[Path]:
    """Write ``semantics.txt``; link names with spaces are joined by ``_``."""
    names = {lk.id: "_".join(lk.name.split()) or f"link_{lk.id}" for lk in ctx.links}
    return [write_semantics(ctx.links, ctx.out_dir / "semantics.txt", names)]
