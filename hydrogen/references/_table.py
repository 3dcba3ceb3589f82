"""The shape of a reference kind given as a table of rows, each a coordinate then numbers (the sines'
terms, the moves): in the C loop's configuration a count and the rows flattened, idle as one row of
zeros with the count 0 (C has no zero-length array); the rows' checks. Not a kind itself (no ``KEY``)."""
from __future__ import annotations

import numpy as np

__all__ = ["RowTable", "number"]


def number(value) -> float:
    """``value`` as a float where the description gives a number (an int or a float, not a bool or a
    string: a quoted "0.05" or a true is a typo there, not a value); TypeError otherwise."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{value!r} is not a number")
    return float(value)


class RowTable:
    """Rows of ``1 + len(columns)`` numbers: a coordinate index, then ``columns`` (their names, in the
    order the description writes them), under the configuration fields ``count`` and ``rows``; each
    field's params.h macro is ``P_REF_`` and its name in capitals."""

    def __init__(self, count: str, rows: str, columns: tuple, key: str | None = None):
        self.count, self.rows, self.columns, self.width = count, rows, tuple(columns), 1 + len(columns)
        #: the description's key of the rows (``reference.<key>``), which messages name (default ``rows``)
        self.key = key or rows
        #: The kind's FIELDS (name, C type, params.h macro).
        self.fields = ((count, "long long", f"P_REF_{count.upper()}"), (rows, "const double*", f"P_REF_{rows.upper()}"))
        #: The kind's IDLE values: no row.
        self.idle = {count: 0, rows: np.zeros(self.width)}

    def sizes(self, values: dict) -> dict:
        """The number of entries the rows' array must hold, from the configuration values."""
        return {self.rows: self.width * max(int(values[self.count]), 1)}

    def axes(self, values: dict) -> list:
        """The coordinate indices the C loop reads from the configuration values (each row's)."""
        return [r[0] for r in np.reshape(values[self.rows], (-1, self.width))[: int(values[self.count])]]

    def config(self, rows) -> dict:
        """The configuration values of ``rows``."""
        rows = tuple(rows)
        return {self.count: len(rows), self.rows: np.array(rows, float).reshape(-1) if rows else np.zeros(self.width)}

    def check(self, rows, fail, axis, finite) -> None:
        """Each row the C loop reads valid (a coordinate, then finite numbers), else ``fail(field, what,
        value)``; ``axis(field, value)`` and ``finite(field, value)`` check one value."""
        shape = f"(axis, {', '.join(self.columns)})"
        if isinstance(rows, (str, bytes)) or not hasattr(rows, "__iter__"):
            fail(f"reference.{self.key}", f"must be a sequence of {shape}", rows)
        for j, row in enumerate(rows):
            if isinstance(row, (str, bytes)) or not hasattr(row, "__len__") or len(row) != self.width:
                fail(f"reference.{self.key}[{j}]", f"must be {shape}", row)
            axis(f"reference.{self.key}[{j}] axis", row[0])
            for name, v in zip(self.columns, row[1:]):
                finite(f"reference.{self.key}[{j}] {name.split()[0]}", v)
