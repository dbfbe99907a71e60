"""Exceptions raised by pdsmc_ros.

Every exception subclasses a built-in so callers can catch it generically
(``except ValueError``) or precisely (``except UnreachableError``).
"""

from __future__ import annotations


class PdsmcError(Exception):
    """Base class of every pdsmc_ros error."""


class InvalidInputError(PdsmcError, ValueError):
    """An argument has the wrong shape, type, range or a non-finite value."""


class UnreachableError(InvalidInputError):
    """A task-space point lies outside the workspace of the manipulator."""


class SingularConfigurationError(InvalidInputError):
    """A configuration where a Jacobian (or the loop-closure Jacobian) is singular."""


class ConfigError(InvalidInputError):
    """A preset, parameter file or named option is unknown or malformed."""


class MissingGainsError(ConfigError):
    """No preset gains for this robot, contour group and controller (give them, or tune)."""


class UnstableRateError(InvalidInputError):
    """The chosen control rate cannot be stable with the chosen gains."""


class BagError(PdsmcError, OSError):
    """A bag cannot be read or written."""


class CdrError(PdsmcError, ValueError):
    """A serialized message is malformed (a live message's content, not an I/O failure)."""
