"""The one exception class a command reports to its user as a single line, without a traceback.

A `UserError` says that what the user asked for or pointed us at is wrong: a flag value, a data
folder, an archive, a checkpoint made by another run. Its message must name the thing and the
problem (and the remedy where there is one), because it is all the user sees
(`fabricjax.cli` prints `error: <message>` and exits with status 2). Anything else that escapes
a command is a bug and keeps its traceback. It subclasses ValueError, so code that catches
ValueError keeps working; ValueErrors raised elsewhere (numpy, JAX) are not user errors.
"""


class UserError(ValueError):
    """A mistake in the user's input, reported as one line (see the module docstring)."""
