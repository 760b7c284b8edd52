"""Which rows of the group QPs' duals were active, remembered across solves (`planner.scp.dual`).

A group's dual is solved over a working set of rows (`planner.scp.dual.GroupDual.solve`); the rows
found active by the latest solve that held them start the next solve that holds them again.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["ActiveRows"]

Keys = NDArray[np.int64]


class ActiveRows:
    """Ids of the rows that had a positive multiplier in the latest solve that held them: the
    warm start of the next solve of a group that holds them again (the same group with a few
    rows added, or the next SCP iteration's group, whose active set changes little).

    Separation rows are named by the caller (`solve_group_dual`'s `row_ids`); box rows by
    (vehicle, functional, axis, side), computed here."""

    def __init__(self) -> None:
        # Sets: a group's lookups and updates cost its own rows, not everything remembered.
        self._separation: set[int] = set()
        self._boxes: set[int] = set()

    @property
    def separation(self) -> Keys:
        """The remembered active separation rows, sorted."""
        return np.array(sorted(self._separation), dtype=np.int64)

    def known(self, sep_ids: Keys, box_ids: Keys) -> NDArray[np.bool_]:
        """Per row (separation rows, then box rows): remembered active?"""
        sep, box = self._separation, self._boxes
        return np.array([x in sep for x in sep_ids.tolist()]
                        + [x in box for x in box_ids.tolist()], dtype=bool)

    def update(self, sep_ids: Keys, sep_active: NDArray[np.bool_], box_ids: Keys,
               box_active: NDArray[np.bool_]) -> None:
        """Forget what was known of these rows and remember which of them are active."""
        self._separation.difference_update(sep_ids.tolist())
        self._separation.update(sep_ids[sep_active].tolist())
        self._boxes.difference_update(box_ids.tolist())
        self._boxes.update(box_ids[box_active].tolist())
