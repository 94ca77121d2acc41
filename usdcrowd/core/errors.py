"""The errors a user's mistake raises.

Every one formats as a single line naming the file, the prim and the
attribute, so the CLI can print it and exit 2 without a traceback.
"""

from __future__ import annotations


class UsdcrowdError(Exception):
    """A problem with the user's input, reported as one line.

    Parameters
    ----------
    message : str
        What is wrong, and if possible what to do.
    file : str, optional
        The file (stage, layer or image) concerned.
    prim : str, optional
        The prim path concerned.
    attribute : str, optional
        The attribute name concerned.
    """

    def __init__(self, message: str, *, file: str | None = None,
                 prim: str | None = None, attribute: str | None = None):
        self.message = message
        self.file = file
        self.prim = prim
        self.attribute = attribute
        super().__init__(str(self))

    def __str__(self) -> str:
        where = self.file or ""
        if self.prim:
            where += f"{':' if where else ''}{self.prim}"
            if self.attribute:
                where += f".{self.attribute}"
        elif self.attribute:
            where += f"{':' if where else ''}{self.attribute}"
        # Keep it on one line whatever the message holds.
        text = " ".join(self.message.split())
        return f"{where}: {text}" if where else text


class StageError(UsdcrowdError):
    """A stage cannot be opened or is not what the command needs."""

    @classmethod
    def at(cls, prim, attribute: str, message: str) -> "StageError":
        """The error about ``prim``'s ``attribute``, naming the layer that authors its strongest opinion
        (where the user has to look), or the stage's root layer when nothing authors it."""
        attr = prim.GetAttribute(attribute)
        stack = attr.GetPropertyStack() if attr else []
        layer = stack[0].layer.identifier if stack else prim.GetStage().GetRootLayer().identifier
        return cls(message, file=layer, prim=str(prim.GetPath()), attribute=attribute)


class ScenarioError(UsdcrowdError):
    """A scenario's values are wrong (out of range, missing asset, empty group)."""


def usd_error_text(exc: BaseException) -> str:
    """The first human message inside a pxr Tf error, without C++ locations."""
    import re

    found = re.findall(r":\s*'(.*?)'\s*(?:\n|$)", str(exc), flags=re.S)
    text = found[0] if found else str(exc)
    return " ".join(text.split())[:200]
