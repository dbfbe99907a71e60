"""A law written in Python, behind the compiled dispatch (numba ``objmode``).

A law registered with a Python torque and no compiled form (:attr:`LawEntry.code` None: a
user's law, a test's own) runs through the same closed loop and the same controller as the
compiled laws: :class:`~pdsmc_ros.control.law.ControlLaw` gives it a code from
:data:`PYTHON_LAW` up, a handle to itself, and :func:`~pdsmc_ros.control.law.law_torque`
calls back into its Python torque for that code (about 3 us a call besides the law's own cost).
"""

from __future__ import annotations

import itertools
import weakref
from typing import Protocol

from numba import njit, objmode

from ..kernels.options import WITH_RUNTIME
from ..robots.base import FloatArray

PYTHON_LAW = 1000
"""The first code of a law written in Python (codes below are compiled forms)."""


class PythonTorque(Protocol):
    def python_torque(self, q: FloatArray, qd: FloatArray, q_ref: FloatArray, qd_ref: FloatArray,
                      qdd_ref: FloatArray, tau: FloatArray) -> None: ...


_LAWS: weakref.WeakValueDictionary[int, PythonTorque] = weakref.WeakValueDictionary()
_NEXT = itertools.count()


def handle(law: PythonTorque) -> int:
    """A code for ``law`` (held weakly): :func:`torque` of that code calls its ``python_torque``."""
    key = next(_NEXT)
    _LAWS[key] = law
    return PYTHON_LAW + key


def _call(code: int, q: FloatArray, qd: FloatArray, q_ref: FloatArray, qd_ref: FloatArray, qdd_ref: FloatArray,
          tau: FloatArray) -> None:
    # copies: the caller's arrays are views of its samples and scratch
    _LAWS[code - PYTHON_LAW].python_torque(q.copy(), qd.copy(), q_ref.copy(), qd_ref.copy(), qdd_ref.copy(), tau)


@njit(**WITH_RUNTIME)
def torque(code, q, qd, q_ref, qd_ref, qdd_ref, tau):  # noqa: ANN001, ANN201, PLR0913
    """The Python law of ``code`` for one state, into ``tau``."""
    with objmode():
        _call(code, q, qd, q_ref, qd_ref, qdd_ref, tau)
