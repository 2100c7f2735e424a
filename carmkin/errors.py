"""Typed errors raised by carmkin.

Every error names the offending field or argument, so that a user can fix the input without reading the
source. All derive from :class:`CarmkinError`, itself a :class:`ValueError`.
"""


class CarmkinError(ValueError):
    """Base class of all carmkin input errors."""


class InvalidParameterError(CarmkinError):
    """A geometry, limit or setup value is not acceptable (NaN, negative length, lower > upper, ...)."""


class PresetError(InvalidParameterError):
    """A preset file is malformed: bad TOML, an unknown section or key, a wrong type or value.

    The message names the file, the key and (for a misspelling) the nearest valid name; values are quoted
    in the preset's units (mm, deg).
    """


class UnknownPresetError(PresetError, KeyError):
    """No preset file of that name ships with carmkin (also for an unknown ``base = "..."``)."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


class InvalidConfigurationError(CarmkinError):
    """A joint configuration has the wrong shape or non-finite values."""


class NearSingularSetupError(InvalidParameterError):
    """The table axis is within a small angle of the C-arm's vertical axis (near singular case a)."""


class InvalidPoseError(CarmkinError):
    """A pose is not a 4x4 rigid transform (wrong shape, NaN/Inf, not orthonormal, det != 1)."""
