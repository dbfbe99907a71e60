"""Control laws: each law once (numpy and compiled forms side by side) and a registry by name.

Adding a law: a :class:`LawEntry` declaring its gains (:class:`GainSpec`), its numpy form
and its linear part, registered with :func:`register_law` (see :mod:`.laws`); preset gains in
``config/gains.yaml`` are optional, a compiled form too (one branch in
:func:`.dispatch.law_torque`).
"""

from .dispatch import compiled_torque
from .gains import Gains
from .law import ControlLaw
from .laws import PD, PDSMC, SMC
from .registry import (
    GAINS,
    LAWS,
    SMC_MODEL_KEYS,
    GainSpec,
    LawEntry,
    LawSetup,
    gain_names,
    law,
    law_label,
    law_names,
    register_law,
    smc_model_vector,
    unregister_law,
)

__all__ = [
    "GAINS",
    "LAWS",
    "PD",
    "PDSMC",
    "SMC",
    "SMC_MODEL_KEYS",
    "ControlLaw",
    "GainSpec",
    "Gains",
    "LawEntry",
    "LawSetup",
    "compiled_torque",
    "gain_names",
    "law",
    "law_label",
    "law_names",
    "register_law",
    "smc_model_vector",
    "unregister_law",
]
