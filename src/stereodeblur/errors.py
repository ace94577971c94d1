"""Errors for bad input. The CLI prints them as one line and exits with code 2."""

from __future__ import annotations


class InputError(ValueError):
    """Input data (a file, a value, an argument) is not what was expected.

    The message names the file or value and says what was expected. When a
    library parameter is at fault (or can supply what is missing), ``parameter``
    names it, e.g. ``'exposure'``, so a front end can point at its own option.

    Parameters
    ----------
    message : str
        One line.
    parameter : str, optional
        The library parameter concerned.
    """

    def __init__(self, message: str = "", *, parameter: str | None = None):
        super().__init__(message)
        self.parameter = parameter
