"""Errors for bad input. The CLI prints them as one line and exits with code 2."""


class InputError(ValueError):
    """Input data (a file, a value, an argument) is not what was expected.

    The message names the file or value and says what was expected.
    """
