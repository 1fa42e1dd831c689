"""Exception types shared by every package of the suite.

:class:`InputError` is raised for anything a user can fix (a bad file, a bad parameter, a volume
without a surface).  The command line turns it into a one-line message and exit code 2.
"""


class InputError(ValueError):
    """Invalid user input: the message names the problem and, where possible, the fix."""
