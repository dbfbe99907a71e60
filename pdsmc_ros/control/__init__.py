"""Control laws: each law once (numpy and compiled forms side by side) and a registry by name.

Adding a law: a :class:`LawEntry` with its numpy form registered with
:func:`register_law` (see :mod:`.laws`) and its gains in ``config/gains.yaml``;
a compiled form is optional (one branch in :func:`.laws.compiled_torque`).
"""

from .gains import Gains
from .law import ControlLaw
from .laws import PD, PDSMC, SMC, compiled_torque
from .registry import (
    GAIN_NAMES,
    LAWS,
    SMC_MODEL_KEYS,
    LawEntry,
    LawSetup,
    law,
    law_label,
    law_names,
    register_law,
    smc_model_vector,
    unregister_law,
)

__all__ = [
    "GAIN_NAMES",
    "LAWS",
    "PD",
    "PDSMC",
    "SMC",
    "SMC_MODEL_KEYS",
    "ControlLaw",
    "Gains",
    "LawEntry",
    "LawSetup",
    "compiled_torque",
    "law",
    "law_label",
    "law_names",
    "register_law",
    "smc_model_vector",
    "unregister_law",
]
