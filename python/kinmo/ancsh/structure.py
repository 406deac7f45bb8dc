"""Category-level kinematic structure for ANCSH.

ANCSH (Li et al. CVPR 2020) is category-level: every object of a category must share one
kinematic structure, a fixed number of rigid parts and joints of fixed types. Part 0 is the
base; joint ``j`` connects part ``j + 1`` (its child) to ``parents[j + 1]``.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class KinematicStructure:
    """A category's kinematic structure.

    Attributes
    ----------
    parents : tuple of int
        Parent part of each part; ``parents[0] == -1`` (the base).
    joint_types : tuple of str
        ``"revolute"`` or ``"prismatic"`` for joint ``j`` (child part ``j + 1``).
    """

    parents: tuple[int, ...]
    joint_types: tuple[str, ...]

    def __post_init__(self) -> None:
        if len(self.parents) < 2 or self.parents[0] != -1:
            raise ValueError(f"structure needs a base part 0 with parent -1 and >= 1 child, got parents {self.parents}")
        if len(self.joint_types) != len(self.parents) - 1:
            raise ValueError(f"{len(self.parents)} parts need {len(self.parents) - 1} joints, got {len(self.joint_types)}")
        for k, p in enumerate(self.parents[1:], start=1):
            if not 0 <= p < k:
                raise ValueError(f"part {k}: parent {p} must be an earlier part")
        for t in self.joint_types:
            if t not in ("revolute", "prismatic"):
                raise ValueError(f"unknown joint type {t!r} (revolute or prismatic)")

    @property
    def n_parts(self) -> int:
        """Number of rigid parts K."""
        return len(self.parents)

    @property
    def n_joints(self) -> int:
        """Number of joints J = K - 1."""
        return len(self.joint_types)

    def signature(self) -> str:
        """Compact text form, e.g. ``"0<R-1,0<P-2"`` (parent<type-child)."""
        return ",".join(
            f"{self.parents[j + 1]}<{t[0].upper()}-{j + 1}" for j, t in enumerate(self.joint_types)
        )
