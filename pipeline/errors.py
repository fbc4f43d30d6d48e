"""The one exception type for bad user input.

Library code raises :class:`InputError` (a ``ValueError``) naming the file or field and
what was expected; the command line turns it into one line on stderr and exit code 2.
Expected outcomes (unstable, budget spent, a simulation that blew up) are statuses in
result objects, never exceptions.
"""

from __future__ import annotations


class InputError(ValueError):
    """Bad input: the message is one line saying what is wrong, where, and what to do."""
