"""Config validation with pydantic, reported as one-line :class:`DroptowerError`.

All config models forbid unknown fields (a misspelt field is an error, not silently
ignored) and are validated in SI units.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, TypeVar

from pydantic import BaseModel, ConfigDict, ValidationError

from droptower.errors import DroptowerError

M = TypeVar("M", bound=BaseModel)


class StrictModel(BaseModel):
    """Base of every config model: unknown fields are errors, values are checked on assignment."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True, frozen=False, allow_inf_nan=False)


def describe_location(loc: tuple[Any, ...], data: Any, name_item: Callable[[str, int, Any], str] | None = None) -> str:
    """Turn a pydantic error location into words: ``element 3 (elastoslide): field p``.

    ``name_item(list_name, index, item)`` names an entry of a list (``element 3 (kind)``).
    """
    words: list[str] = []
    node = data
    i = 0
    parts = list(loc)
    while i < len(parts):
        part = parts[i]
        if isinstance(part, str) and i + 1 < len(parts) and isinstance(parts[i + 1], int):
            index = parts[i + 1]
            item = node.get(part, [None])[index] if isinstance(node, dict) and isinstance(node.get(part), list) and index < len(node.get(part)) else None
            if name_item is not None:
                words.append(name_item(part, index, item))
            else:
                words.append(f"{part}[{index}]")
            node = item
            i += 2
            # pydantic puts the discriminator tag after a list index of a tagged union
            if i < len(parts) and isinstance(item, dict) and parts[i] == item.get("kind"):
                i += 1
            continue
        if isinstance(part, int):
            words.append(f"[{part}]")
        else:
            words.append(f"field {part}")
        node = node.get(part) if isinstance(node, dict) else None
        i += 1
    return ": ".join(words)


def validate(model: type[M], data: dict[str, Any], file: str | Path | None,
             name_item: Callable[[str, int, Any], str] | None = None) -> M:
    """Validate ``data`` against ``model``; the first problem becomes a one-line error."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        errors = exc.errors(include_url=False)
        # a misspelt field shows as that field unknown and the right one missing: name the typo
        err = next((e for e in errors if e["type"] == "extra_forbidden"), errors[0])
        where = describe_location(tuple(err["loc"]), data, name_item) or None
        msg = err["msg"].removeprefix("Value error, ")  # pydantic's prefix for a validator's ValueError
        if err["type"] == "extra_forbidden":
            msg = "unknown field"
        elif err["type"] == "missing":
            msg = "missing field"
        raise DroptowerError(msg, file=file, where=where) from None
