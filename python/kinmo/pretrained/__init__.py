"""Pretrained model bundles shipped inside the package (issue 22).

Each sub-folder holding a ``bundle.json`` is a model bundle (:mod:`kinmo.inference.bundle`):
the motion GNN, the axis-selection network and the learned selector's ``ranker.json``, with
a ``LICENSE`` beside the weights. ``kinmo predict`` uses :data:`DEFAULT_MODEL` when no
``--model`` is given; ``kinmo models`` lists what is installed.

The code of kinmo is MIT-licensed; the **weights** are trained on PartNet-Mobility and
PartNet objects and carry their terms: non-commercial research and education only
(``LICENSE`` of each bundle, ``docs/model_card.md``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from kinmo.errors import KinmoDataError

__all__ = ["DEFAULT_MODEL", "PRETRAINED_DIR", "InstalledModel", "default_model", "installed_models",
           "is_pretrained", "license_notice"]

#: The folder of the packaged bundles.
PRETRAINED_DIR = Path(__file__).resolve().parent
#: Name of the bundle ``kinmo predict`` uses without ``--model``.
DEFAULT_MODEL = "partnet-mobility-v1"


@dataclass(frozen=True)
class InstalledModel:
    """One packaged bundle, as ``kinmo models`` lists it.

    Attributes
    ----------
    name : str
        Its folder name (``--model NAME`` is not accepted: pass :attr:`path`).
    path : Path
        The bundle folder.
    selector : str
        ``ranker`` (learned), ``paper`` or ``none``, from ``bundle.json``.
    n_trained_on : int
        Objects it was trained on (``trained_on`` of ``bundle.json``).
    size_bytes : int
        Bytes of its files.
    license : str
        First line of its ``LICENSE`` file ("" when there is none).
    """

    name: str
    path: Path
    selector: str
    n_trained_on: int
    size_bytes: int
    license: str


def installed_models(root: str | Path = PRETRAINED_DIR) -> list[InstalledModel]:
    """The bundles below ``root`` (default: the packaged ones), sorted by name.

    A folder whose ``bundle.json`` cannot be read is left out (``kinmo predict --model`` on
    it names the problem).
    """
    out = []
    for d in sorted(Path(root).iterdir()):
        f = d / "bundle.json"
        if not f.is_file():
            continue
        try:
            doc = json.loads(f.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        lic = d / "LICENSE"
        first = lic.read_text(encoding="utf-8").strip().splitlines()[0] if lic.is_file() else ""
        size = sum(p.stat().st_size for p in d.rglob("*") if p.is_file())
        out.append(InstalledModel(d.name, d, str(doc.get("selector", "")),
                                  len(doc.get("trained_on") or []), size, first))
    return out


def default_model() -> Path:
    """The folder of :data:`DEFAULT_MODEL`.

    Raises
    ------
    KinmoDataError
        It is not installed (a source checkout without the packaged weights).
    """
    path = PRETRAINED_DIR / DEFAULT_MODEL
    if not (path / "bundle.json").is_file():
        raise KinmoDataError(path, "the pretrained model is not installed: give --model (a bundle of "
                                   "`kinmo train all`, runs/all/model)")
    return path


def is_pretrained(path: str | Path) -> bool:
    """True when ``path`` is (inside) a packaged bundle."""
    try:
        Path(path).resolve().relative_to(PRETRAINED_DIR)
    except ValueError:
        return False
    return True


def license_notice(path: str | Path) -> str:
    """The one line said when a packaged bundle is used: its name and its terms."""
    p = Path(path).resolve()
    name = p.relative_to(PRETRAINED_DIR).parts[0] if is_pretrained(p) else p.name
    return (f"pretrained model {name}: weights trained on PartNet-Mobility/PartNet, for non-commercial "
            f"research and education only ({PRETRAINED_DIR / name / 'LICENSE'})")
