"""Rig logs: the measured quantities identification works from, as a CSV file with named columns.

A log holds, per sample k (one row), at a uniform sample rate:

* ``t`` (s): sample time, strictly increasing, uniform spacing (jitter ≤ 1 %);
* ``l0`` … ``l{m-1}``: each actuator's measured travel in its kind's unit (``TRAVEL``): a cylinder's
  length in m, a joint actuator's angle in rad;
* ``pc0`` … ``pc{N-1}`` (Pa): the measured pressure vector (:mod:`hydrogen.pressures`): the control-chamber
  (cap side) pressure of each three-way cylinder (N = m), p_A and p_B of each four-way one or rotary actuator;
* ``u0`` … ``u{m-1}`` (m): spool commands, each held from t_k to t_{k+1} (zero-order hold);
  optional: without them only θ is estimated, not γ;
* ``ps0`` (Pa): the measured supply pressure, on a robot whose ``[supply]`` is a state (a pump); a
  constant supply has no such column.

m is the number of cylinders of the model. Other columns are ignored (a simulated log also carries
the true pose ``q0`` … ``q{n-1}`` and each other plant output a rig part declares, ``<name>0`` …, true
values in the part's unit). Lines starting with ``#`` are comments; a log written by
hydrogen starts with ``# hydrogen log`` and a JSON line of metadata (scenario, controller, sensor
noise added, and for a simulated log the true θ and γ). Values are written with ``repr`` (exact).
Columns are separated by commas; a file separated by tabs (header and rows alike) is read too.

A :class:`~hydrogen.simulation.simulator.SimulationResult` records the *true* leg lengths and
pressures of the plant. :func:`log_from_result` makes a log from it and adds white sensor noise of
the given standard deviations (``noise_l`` m, ``noise_p`` Pa on every pressure, the supply's too,
seeded), i.e. what a rig's sensors would have measured; the noise added is recorded in the metadata.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import IdentificationError, OutputPathError
from .fileio import atomic_write
from .layout import SUPPLY_LOG
from .setting import is_number

__all__ = ["Log", "log_from_result", "write_log", "read_log", "as_log"]

_MAGIC = "# hydrogen log"


@dataclass
class Log:
    """Measured time series of one run: ``t`` (N,), ``columns`` name -> (N,) arrays, ``meta``."""

    t: np.ndarray
    columns: dict
    meta: dict = field(default_factory=dict)
    source: str = "<memory>"

    def group(self, prefix: str, m: int, required: bool = True, what: str = "cylinders"):
        """The (N, m) array of columns ``{prefix}0`` … ``{prefix}{m-1}``; None when the whole group is
        absent and not ``required``; an :class:`IdentificationError` naming the missing columns otherwise,
        and ``what`` the m columns stand for ("cylinders", "pressure states")."""
        names = [f"{prefix}{i}" for i in range(m)]
        missing = [c for c in names if c not in self.columns]
        if missing and (required or len(missing) < m):
            needs = names[0] if m == 1 else f"{names[0]}..{names[-1]}"
            raise IdentificationError(
                f"{self.source}: log is missing column(s) {', '.join(missing)} (needs {needs}: {what}; columns "
                f"present: {', '.join(['t', *self.columns]) or 'none'})")
        if missing:
            return None
        return np.column_stack([self.columns[c] for c in names])

    @property
    def n_samples(self) -> int:
        """Number of samples (rows) in the log."""
        return len(self.t)


def log_from_result(res, noise_l: float = 0.0, noise_p: float = 0.0, seed: int = 0) -> Log:
    """A log of a simulation: its leg lengths and pressures plus white sensor noise of standard
    deviation ``noise_l`` (m) and ``noise_p`` (Pa) from a generator seeded with ``seed``, and its
    spool commands. The true pose and parameters are kept as extra columns and metadata."""
    for name, v in (("noise_l", noise_l), ("noise_p", noise_p)):
        if not (is_number(v) and np.isfinite(v) and v >= 0):
            raise IdentificationError(f"{name} must be a finite number >= 0, got {v!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise IdentificationError(f"seed must be an integer >= 0 (the noise's generator), got {seed!r}")
    rng = np.random.default_rng(seed)
    l = np.asarray(res.leg_lengths, float)
    pc = np.asarray(res.pressures, float)
    l_meas = l + noise_l * rng.standard_normal(l.shape) if noise_l else l.copy()
    pc_meas = pc + noise_p * rng.standard_normal(pc.shape) if noise_p else pc.copy()
    ps = getattr(res, "supply_pressure", None)  # None: a constant supply, no column
    supply = []
    if ps is not None:  # a pressure sensor like the others, its noise drawn after theirs
        ps = np.asarray(ps, float).reshape(len(pc), -1)
        supply = [(SUPPLY_LOG, ps + noise_p * rng.standard_normal(ps.shape) if noise_p else ps.copy())]
    # the plant's other outputs (a rig part's states), true values like q
    others = [(name, np.asarray(v, float).reshape(len(pc), -1)) for name, v in getattr(res, "plant", {}).items()
              if name != SUPPLY_LOG]
    cols = {}
    for prefix, arr in (("l", l_meas), ("pc", pc_meas), *supply,
                        ("u", np.asarray(getattr(res, "u_applied", res.u), float)), ("q", np.asarray(res.q, float)),
                        *others):
        for i in range(arr.shape[1]):
            cols[f"{prefix}{i}"] = arr[:, i]
    measured = "l, pc and ps are" if supply else "l and pc are"
    meta = {"model": getattr(res, "model_name", ""), "scenario": res.scenario_name, "controller": res.controller,
            "noise_l": float(noise_l),
            "noise_p": float(noise_p), "seed": int(seed), "theta_true": np.asarray(res.theta_true).tolist(),
            "gamma_true": np.asarray(res.gamma_true).tolist(),
            "note": f"{measured} the simulated true values plus the sensor noise above; q is the true pose"
                    + "".join(f", {name} the true {name}" for name, _ in others)}
    return Log(np.asarray(res.t, float).copy(), cols, meta, source=f"simulation {res.scenario_name}/{res.controller}")


def write_log(log, path) -> Path:
    """Write a :class:`Log` (or a SimulationResult, without noise) as CSV; returns the path."""
    from .outputs import check_output_file

    log = log if isinstance(log, Log) else log_from_result(log)
    if not isinstance(path, (str, os.PathLike)):
        raise OutputPathError(f"log file: a path (str or pathlib.Path) is needed, got {type(path).__name__} {path!r}")
    path = check_output_file(path, "log file")  # a folder, a path under a file: named, before writing
    names = ["t", *log.columns]
    data = np.column_stack([log.t, *log.columns.values()]) if len(log.t) else np.zeros((0, len(names)))
    lines = [_MAGIC, "# " + json.dumps(log.meta, sort_keys=True), ",".join(names)]
    lines += [",".join(map(repr, map(float, row))) for row in data]
    atomic_write(path, "\n".join(lines) + "\n")
    return path


def read_log(path) -> Log:
    """Read a CSV log (see the module docstring). Every error names the file, and the line or column."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")  # a BOM (spreadsheets save one) is no part of the header
    except FileNotFoundError:
        raise IdentificationError(f"{path}: log file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise IdentificationError(f"{path}: cannot read log file: {exc}") from None
    meta, header, rows, header_line = {}, None, [], 0
    for lineno, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if not s:
            continue
        if s.startswith("#"):
            if header is None and s.startswith("# {"):
                try:
                    meta = json.loads(s[1:])
                except json.JSONDecodeError:
                    meta = {}
            continue
        if header is None:
            sep = _delimiter(path, lineno, s)
            header, header_line = [c.strip() for c in s.split(sep)], lineno
            continue
        rows.append((lineno, s))
    if header is None:
        raise IdentificationError(f"{path}: no header line (expected column names such as t,l0,l1,...)")
    dup = sorted({c for c in header if header.count(c) > 1})
    if dup or "" in header:
        raise IdentificationError(f"{path}: line {header_line}: header has "
                                  + (f"duplicate column(s) {', '.join(dup)}" if dup else "an empty column name"))
    if "t" not in header:
        raise IdentificationError(f"{path}: log is missing column t (time, s); columns present: {', '.join(header)}")
    data = np.empty((len(rows), len(header)))
    for k, (lineno, s) in enumerate(rows):
        cells = s.split(sep)
        if len(cells) != len(header):
            other = next((d for d in _DELIMITERS if d != sep and d in s), None)
            if other is not None:
                raise IdentificationError(
                    f"{path}: line {lineno}: values separated by {_DELIMITERS[other]}, but the header (line "
                    f"{header_line}) by {_DELIMITERS[sep]}: use one delimiter throughout, a comma")
            raise IdentificationError(f"{path}: line {lineno}: {len(cells)} values, header has {len(header)} columns")
        try:
            data[k] = [float(c) for c in cells]
        except ValueError:
            bad = next(i for i, c in enumerate(cells) if not _is_float(c))
            raise IdentificationError(f"{path}: line {lineno}, column {header[bad]}: not a number: "
                                      f"{cells[bad].strip()!r}") from None
    cols = {name: data[:, i] for i, name in enumerate(header) if name != "t"}
    return Log(data[:, header.index("t")], cols, meta, source=str(path))


#: Column delimiters a log may use (a comma, as hydrogen writes, or a tab) and their names.
_DELIMITERS = {",": "commas", "\t": "tabs", ";": "semicolons"}


def _delimiter(path, lineno, header: str) -> str:
    """The header's delimiter: a comma, else a tab; anything else is refused, naming the line."""
    if "," in header:
        return ","
    if "\t" in header:
        return "\t"
    if ";" in header or " " in header.strip():
        found = "semicolons" if ";" in header else "spaces"
        raise IdentificationError(f"{path}: line {lineno}: the header {header[:80]!r} is separated by {found}: "
                                  f"the delimiter must be a comma (or a tab), e.g. t,l0,l1,...")
    return ","


def _is_float(s) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def _checked_log(log: Log) -> Log:
    """A :class:`Log` made by hand, checked as the other routes check theirs: ``t`` one column of
    numbers, ``columns`` a mapping of names to columns of numbers as long as ``t``, ``meta`` a dict."""
    where = getattr(log, "source", "<memory>")
    try:
        t = np.asarray(log.t, dtype=float)
    except (TypeError, ValueError):
        t = None
    if t is None or t.ndim != 1:
        raise IdentificationError(f"{where}: the log's t must be one column of times (s), got {type(log.t).__name__}")
    if not hasattr(log.columns, "items"):
        raise IdentificationError(f"{where}: the log's columns must map names to columns, got "
                                  f"{type(log.columns).__name__}")
    if not isinstance(log.meta, dict):
        raise IdentificationError(f"{where}: the log's meta must be a dict, got {type(log.meta).__name__}")
    for name, col in log.columns.items():
        try:
            c = np.asarray(col, dtype=float)
        except (TypeError, ValueError):
            raise IdentificationError(f"{where}: column {name} must be numbers") from None
        if c.shape != t.shape:
            held = c.shape[0] if c.ndim == 1 else f"shape {c.shape} of"
            raise IdentificationError(f"{where}: column {name} holds {held} values, t holds {len(t)}: every "
                                      "column has one value per time")
    return log


def as_log(obj) -> Log:
    """A :class:`Log` from a Log, a SimulationResult (true values, no noise added), a CSV path, or a
    mapping of column names to arrays (a dict or a pandas DataFrame)."""
    if isinstance(obj, Log):
        return _checked_log(obj)
    if isinstance(obj, (str, Path)):
        return read_log(obj)
    if hasattr(obj, "leg_lengths") and hasattr(obj, "pressures") and hasattr(obj, "t"):
        return log_from_result(obj)
    if hasattr(obj, "keys") and hasattr(obj, "__getitem__"):
        names = [str(k) for k in obj.keys()]
        if "t" not in names:
            raise IdentificationError(f"log is missing column t (time, s); columns present: {', '.join(names)}")
        try:
            cols = {str(k): np.asarray(obj[k], dtype=float).reshape(-1) for k in obj.keys()}
        except (TypeError, ValueError) as exc:
            raise IdentificationError(f"log columns must be numbers: {exc}") from None
        lengths = {k: len(v) for k, v in cols.items()}
        if len(set(lengths.values())) > 1:
            raise IdentificationError(f"log columns have different lengths: {lengths}")
        t = cols.pop("t")
        return Log(t, cols, {}, source="<columns>")
    raise IdentificationError(f"a log must be a SimulationResult, a CSV path, a hydrogen Log or a mapping of "
                              f"columns, not {type(obj).__name__}")

