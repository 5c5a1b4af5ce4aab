"""Exceptions that the command line turns into one clear line and exit code 2."""


class UserError(Exception):
    """A mistake in the user's input (a file, an option, a value).

    The CLI prints ``akc-drake: error: <message>`` and exits with code 2, never a traceback.
    The message names the file, line or field and the offending value.
    """


class SourceError(UserError):
    """A camera source could not be opened or stopped delivering frames."""
