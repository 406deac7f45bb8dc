"""Names in a kinmo run folder that several stages share (the pipeline writes, the report and
the CLI read), kept apart from :mod:`kinmo.pipeline` so readers need not import the pipeline.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["ANCSH_SEEDS_DIR", "DEFAULT_RUN", "RESULT_FILE", "SYNTH_EXTRA_FILE", "TABLE2_SEED_STAGE"]

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
