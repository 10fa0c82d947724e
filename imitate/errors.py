"""The one root exception of the project; every user-facing error is an ``ImitateError``."""


class ImitateError(Exception):
    """Bad input or an unusable environment: the message names the value and what is accepted."""
