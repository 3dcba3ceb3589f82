"""A raw step on one coordinate: q_d = bias + height e_axis from t_step on, its derivatives zero (the
step responses of the paper's Fig. 8)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._table import number

__all__ = ["KEY", "SYNTAX", "Reference", "Step"]

KEY = "step"
SYNTAX = "{ coordinate, height, time }"

FIELDS = (("step_axis", "long long", "P_REF_STEP_AXIS"), ("step_height", "double", "P_REF_STEP_HEIGHT"),
          ("t_step", "double", "P_REF_T_STEP"))
COMMENT = "a raw step of step_height on coordinate step_axis (>= 0) at t_step"
#: No step: its axis -1.
IDLE = {"step_axis": -1, "step_height": 0.0, "t_step": 0.0}
C_BODY = """\
    if (c->step_axis >= 0 && c->step_axis < NQ && t >= c->t_step) qd[c->step_axis] += c->step_height;
"""


def sizes(values: dict) -> dict:
    """The number of entries each of its configuration arrays must hold (none: scalars)."""
    return {}


def axes(values: dict) -> list:
    """The coordinate index the C loop reads from the values (none when the step is idle)."""
    return [values["step_axis"]] if values["step_axis"] >= 0 else []


@dataclass(frozen=True)
class Reference:
    """q_d = bias + height e_axis for t ≥ t_step (a raw step, derivatives zero, as in Fig. 8)."""

    bias: np.ndarray
    axis: int
    height: float
    t_step: float

    STEP_RESPONSE = True

    @classmethod
    def parse(cls, value, axis, bias):
        """From the description's ``{ coordinate, height, time }``."""
        return cls(bias, axis(value["coordinate"]), number(value["height"]), number(value["time"]))

    def __call__(self, t: float):
        q = np.array(self.bias, float)
        if t >= self.t_step:
            q[self.axis] += self.height
        n = q.size
        return [q, np.zeros(n), np.zeros(n), np.zeros(n)]

    def positions(self, t) -> np.ndarray:
        t = np.asarray(t, float)
        out = np.tile(np.asarray(self.bias, float), (t.size, 1))
        out[t >= self.t_step, self.axis] += self.height
        return out

    def velocities(self, t) -> np.ndarray:
        """Zero (a raw step has no derivative but at the step itself, which the loop never samples)."""
        return np.zeros((np.asarray(t, float).size, len(self.bias)))

    def amplitude(self) -> np.ndarray:
        amp = np.zeros(len(self.bias))
        amp[self.axis] = abs(self.height)
        return amp

    def frequencies(self) -> tuple:
        """None: a step is not periodic."""
        return ()

    def check(self, fail, axis, finite) -> None:
        """The axis, height and step time the C loop reads valid, else ``fail(field, what, value)``."""
        axis("reference.axis", self.axis)
        finite("reference.height", self.height)
        finite("reference.t_step", self.t_step)

    def config(self) -> dict:
        """Its values of FIELDS."""
        return {"step_axis": int(self.axis), "step_height": float(self.height), "t_step": float(self.t_step)}


#: Its former name (hydrogen.simulation.reference.Step).
Step = Reference
