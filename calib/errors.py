"""The errors viewcomp raises for bad input: each message names the thing at fault and the fix.

Every refusal of an input, an option or an output derives from :class:`ViewcompError`; the
command line catches exactly these (exit status 2, the message alone). Any other exception
is a bug in viewcomp: the command line prints its traceback with a note asking to report it
(exit status 1).
"""

from __future__ import annotations


class ViewcompError(Exception):
    """A bad input, option or output, refused before anything is lost.

    The message names the file, option or value at fault, the cause and what to do.
    """


class FitError(ViewcompError, ValueError):
    """A fit that cannot succeed from these captures.

    ``capture`` names the capture at fault (e.g. ``"screen/ramp"``), ``reason`` says why and
    what to change.
    """

    def __init__(self, capture: str, reason: str) -> None:
        super().__init__(f"{capture}: {reason}")
        self.capture = capture
        self.reason = reason


class OutputError(ViewcompError, ValueError):
    """An output path that would overwrite an input, or that cannot be written."""
