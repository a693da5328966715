"""Comma-separated option values (--levels 0,1,2, --models flat,phong, --shininess 10,100): split, converted and
checked, with one OptionError naming the option and what it allows."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

from ..errors import OptionError


def items(text: str) -> list[str]:
    """'a, b,,c' → ['a', 'b', 'c']."""
    return [item.strip() for item in text.split(",") if item.strip()]


def numbers(text: str | None, kind: Callable[[str], Any], option: str) -> tuple | None:
    """'0,1,2' → (0, 1, 2) with `kind` (int, float); None stays None."""
    if text is None:
        return None
    try:
        return tuple(kind(item) for item in text.split(",") if item.strip())
    except ValueError:
        raise OptionError(f"{option}: expected numbers separated by commas, got {text!r}") from None


def choices(text: str | None, allowed: Iterable[str], option: str, kind: Callable[[str], Any] = str) -> tuple | None:
    """'flat,phong' → (kind('flat'), kind('phong')), each one of `allowed`; None stays None."""
    if text is None:
        return None
    allowed = [str(getattr(a, "value", a)) for a in allowed]
    found = items(text)
    for item in found:
        if item not in allowed:
            raise OptionError(f"{option}: {item!r} is not one of {', '.join(allowed)}")
    return tuple(kind(item) for item in found)
