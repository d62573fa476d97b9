"""The one exception type curveskel raises for bad input or a failed run."""

__all__ = ["CurveSkelError"]


class CurveSkelError(ValueError):
    """Input curveskel cannot skeletonize, or a stage that cannot go on.

    The message is written for the user (the Blender operator shows it as is, the command
    line prints it without a traceback).
    """
