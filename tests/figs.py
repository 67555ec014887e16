"""Helpers of the report tests: an axes of a page by its gid, the text of a drawn table."""

from __future__ import annotations


def ax(fig, gid):
    """The axes of ``fig`` whose gid is ``gid`` (the report names its panels)."""
    return next(a for a in fig.axes if a.get_gid() == gid)


def cells(axis) -> list[list[str]]:
    """Text of a table drawn on ``axis``: header row first."""
    d = axis.tables[0].get_celld()
    n_r = 1 + max(i for i, _ in d)
    n_c = 1 + max(j for _, j in d)
    return [[d[i, j].get_text().get_text() for j in range(n_c)] for i in range(n_r)]
