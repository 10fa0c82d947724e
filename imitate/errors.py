"""The one root exception of the project; every user-facing error is an ``ImitateError``."""


class ImitateError(Exception):
    """Bad input or an unusable environment: the message names the value and what is accepted."""


def quoted(value: object, limit: int = 60) -> str:
    """``repr(value)`` for an error line, at most ``limit`` characters (a cut one ends in
    "...")."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[: limit - 3]}..."
