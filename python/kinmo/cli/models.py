"""``kinmo models``: the pretrained model bundles installed with the package (issue 22)."""

from __future__ import annotations

from kinmo.cli._apps import app


@app.command("models")
def models_cmd() -> None:
    """List the pretrained model bundles installed with kinmo (the default is what `kinmo
    predict` uses without --model). Their weights are for non-commercial research and
    education only (PartNet-Mobility's terms; LICENSE beside each)."""
    from rich.table import Table

    from kinmo.pretrained import DEFAULT_MODEL, installed_models
    from kinmo.progress import LOG_WIDTH, literal
    from kinmo.progress import console as new_console

    console = new_console()
    if not console.is_terminal:  # logs: wide lines
        console = new_console(width=max(console.width, LOG_WIDTH))
    found = installed_models()
    if not found:
        console.print("no pretrained model installed (give --model: a bundle of `kinmo train all`)")
        return
    t = Table("name", "default", "selector", "trained on", "size", "license", "path")
    for c in t.columns:  # a narrow terminal wraps cells, never cuts a path with an ellipsis
        c.overflow = "fold"
    for m in found:
        t.add_row(literal(m.name), "yes" if m.name == DEFAULT_MODEL else "", m.selector,
                  f"{m.n_trained_on} objects", f"{m.size_bytes / 1e6:.1f} MB", literal(m.license),
                  literal(str(m.path)))
    console.print(t)
