"""The one root exception of the project; every user-facing error is an ``ImitateError``; and
how a message shows a value (:func:`quoted`) or a command's word (:func:`shell_word`), and an
error line's words cut to a readable length (:func:`shortened`)."""

import re
import shlex


class ImitateError(Exception):
    """Bad input or an unusable environment: the message names the value and what is accepted."""


def quoted(value: object, limit: int = 60) -> str:
    """``repr(value)`` for an error line, at most ``limit`` characters (a cut one ends in
    "...")."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[: limit - 3]}..."


# The longest word (a run without spaces) an error line shows whole; a longer one (a value read
# from a file, echoed by a check that did not cut it) keeps its start and end.
LONGEST_WORD = 300


def shortened(line: str) -> str:
    """``line`` with each word longer than :data:`LONGEST_WORD` characters cut in its middle
    (``start...[N characters]...end``): a 1 MB value makes no 1 MB error line."""
    def cut(match: re.Match) -> str:
        word = match.group()
        return f"{word[:200]}...[{len(word)} characters]...{word[-60:]}"

    return re.sub(rf"\S{{{LONGEST_WORD + 1},}}", cut, line)


def shell_word(text: object) -> str:
    """``text`` as one word of a shell command to copy from a message: as it is where that is
    safe, else quoted (:func:`shlex.quote`), or as ``$'...'`` with escapes where it holds a
    control character (a newline would otherwise break the message's one line)."""
    text = str(text)
    if text.isprintable():
        return shlex.quote(text)
    escaped = "".join(c if c.isprintable() and c not in "'\\" else
                      f"\\x{ord(c):02x}" if ord(c) < 256 else f"\\u{ord(c):04x}" for c in text)
    return f"$'{escaped}'"
