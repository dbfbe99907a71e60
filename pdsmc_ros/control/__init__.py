"""Control laws: each law once, a registry by name.

The thesis's PD, SMC and PD-SMC (:mod:`.laws`), the model-based baselines PD + gravity and
computed torque (:mod:`.baselines`) and the super-twisting and integral sliding laws
(:mod:`.sliding`, with an internal state), each written once, compiled. Adding a law: a
:class:`LawEntry` declaring its gains (:class:`GainSpec`), its torque (written in Python, or a
compiled form: its code and one branch in :func:`.law.law_torque`), its linear part and,
optionally, its state (``state_size``) and whose presets it derives from (``presets_from``,
``derive_presets``), declared as an entry point of ``pdsmc_ros.laws`` (:mod:`pdsmc_ros.plugins`:
the built-in ones in this package, a user's in a package of its own) or registered in-process with
:func:`register_law`; preset gains in ``config/gains.yaml`` are optional.
"""

from .law import ControlLaw, compiled_torque
from .laws import PD, PDSMC, SMC
from .registry import (
    GAINS,
    LAWS,
    SMC_MODEL_KEYS,
    Gains,
    GainSpec,
    LawEntry,
    LawSetup,
    gain_names,
    gain_specs,
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
    "gain_specs",
    "law",
    "law_label",
    "law_names",
    "register_law",
    "smc_model_vector",
    "unregister_law",
]
