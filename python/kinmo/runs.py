"""Names in a kinmo run folder that several stages share (the pipeline writes, the report and
the CLI read), kept apart from :mod:`kinmo.pipeline` so readers need not import the pipeline.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["ANCSH_SEEDS_DIR", "DEFAULT_RUN", "MEMBERS_DIR", "RESULT_FILE", "SYNTH_EXTRA_FILE", "TABLE2_SEED_STAGE",
           "member_folders"]

#: Run folder of ``kinmo train all`` when ``--out`` is not given (relative to the working
#: folder); ``kinmo eval`` looks for the last run there.
DEFAULT_RUN = Path("runs") / "all"

#: File of a generated-shapes run (``out/synth-extra-*/``) describing it (read by the report).
SYNTH_EXTRA_FILE = "synth_extra.json"

#: File of ``kinmo train all`` naming every stage's outputs and times
#: (:class:`kinmo.pipeline.PipelineResult`; the report reads it first).
RESULT_FILE = "pipeline_result.json"

#: Folder of the ANCSH trainings of the extra seeds (``kinmo train all --ancsh-seeds K``):
#: ``out/ancsh-seeds/seed-<s>/`` holds ``ancsh/``, ``scans/`` and ``eval/`` as the run folder
#: does for the run's own seed.
ANCSH_SEEDS_DIR = "ancsh-seeds"

#: Prefix of the ``pipeline_result.json`` stage listing the Table 2 evaluations of an extra
#: ANCSH seed (``"table2 seed 1"``); the run's own seed is the ``table2`` stage.
TABLE2_SEED_STAGE = "table2 seed "

#: Folder of a motion-GNN run holding its ensemble members: ``<run>/members/<k>/`` (``k`` = 1,
#: 2, ...), each a run folder of a model trained like the run's own with another seed
#: (:attr:`kinmo.train.gnn.Run.members`).
MEMBERS_DIR = "members"


def member_folders(run_dir: str | Path) -> list[Path]:
    """The ensemble members of a motion-GNN run folder (:data:`MEMBERS_DIR`): the
    ``members/<k>/`` folders holding a ``model.pt``, in the order of ``k`` (an integer);
    none for a single model."""
    root = Path(run_dir) / MEMBERS_DIR
    if not root.is_dir():
        return []
    found = [p for p in root.iterdir() if p.name.isdigit() and (p / "model.pt").is_file()]
    return sorted(found, key=lambda p: int(p.name))
