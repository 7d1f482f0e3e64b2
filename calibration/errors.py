"""Typed errors of the calibration core. Each names the problem; callers add the file and row."""

from __future__ import annotations


class CalibrationError(ValueError):
    """Base class of every error raised by :mod:`calibration`."""


class BenchDataError(CalibrationError):
    """Bench data that cannot be fitted or evaluated.

    Attributes
    ----------
    row : int or None
        Index of the offending point in the data set (0-based), when one point is at fault.
    column : str or None
        Name of the offending column, when one column is at fault.
    """

    def __init__(self, message: str, *, row: int | None = None, column: str | None = None):
        super().__init__(message)
        self.row = row
        self.column = column


class InsufficientDataError(BenchDataError):
    """Too few points, or too little spread (one azimuth, no normal incidence), for the method asked."""


class CalibrationFormatError(CalibrationError):
    """A serialised calibration of another format or version, or with missing fields."""


class FitError(CalibrationError):
    """A fit that did not converge to a usable calibration."""


class FieldDataError(BenchDataError):
    """Field data (a time series against the real Sun) that cannot be compared or located: bad times, a site out
    of range, too short a track."""
