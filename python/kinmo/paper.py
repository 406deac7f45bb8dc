"""Numbers the paper reports, the reference rows of kinmo's tables.

Liu et al., *Semi-Weakly Supervised Object Kinematic Motion Prediction*, CVPR 2023. Kept in a
module of their own (no kinmo imports) so the evaluation, the CLI and the report can print the
paper's row next to kinmo's without importing each other.
"""

from __future__ import annotations

__all__ = ["PAPER_TABLE2"]

#: The paper's Table 2 means (ANCSH on partial scans): part rotation error and joint axis
#: angle error (degrees) of ANCSH trained supervised, semi-supervised and semi-weakly
#: supervised (the paper's method).
PAPER_TABLE2: dict[str, dict[str, float]] = {
    "supervised": {"rotation": 23.66, "angle": 3.25},
    "semi": {"rotation": 24.76, "angle": 3.39},
    "semi-weakly": {"rotation": 17.43, "angle": 2.62},
}
