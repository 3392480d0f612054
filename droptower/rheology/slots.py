"""The kernels' named slot offsets, rendered from the records of :mod:`.kinds`.

The numba kernels index an element's parameter slice ``p[po + ...]`` and state slice
``s[so + ...]`` by named module-level integers (compile-time constants for numba), one per slot
a record of :mod:`.kinds` names:

- ``S_<HEADER NAME>``: the common state header (:data:`~droptower.rheology.kinds.HEADER`),
  ``N_HEADER`` its length;
- ``P_<KIND>_<PARAM>``: a named parameter slot; ``P_<KIND>_TABLES``: where the variable-length
  tables of a kind that has them start (the number of its named slots);
- ``S_<KIND>_<INTERNAL>``: a named internal state slot (after the header);
  ``S_<KIND>_BLOCKS``: where the repeated state blocks of a kind that has them start.

The constants are written into ``kernels.py`` itself, between two marker lines, rather than
imported at run time: :mod:`.kinds` imports the kernels (their codes and step functions), so the
kernels cannot import it; and numba's on-disk cache is keyed on the kernel file, so a layout
change must change that file for the cached machine code to be rebuilt. ``tests/test_slots.py``
checks the block against the records; after a record's layout changes, regenerate it with::

    python -m droptower.rheology.slots
"""
from __future__ import annotations

from pathlib import Path

from droptower.rheology import kernels
from droptower.rheology.kinds import HEADER, KINDS

BEGIN = "# ---------------------------------------------------------------- slot offsets (generated)"
END = "# ---------------------------------------------------------------- end of the generated slot offsets"
KERNELS_PY = Path(kernels.__file__)


def _const(name: str) -> str:
    return name.upper()


def slot_offsets() -> dict[str, int]:
    """Every named slot offset of every kernel kind, by constant name, in layout order."""
    named = [(f"S_{_const(name)}", i) for i, name in enumerate(HEADER)] + [("N_HEADER", len(HEADER))]
    for kind in sorted(KINDS.values(), key=lambda k: k.code):
        prefix = _const(kind.name)
        named += [(f"P_{prefix}_{_const(name)}", i) for i, name in enumerate(kind.params)]
        if kind.n_params is not None:
            named.append((f"P_{prefix}_TABLES", len(kind.params)))
        named += [(f"S_{prefix}_{_const(name)}", len(HEADER) + i) for i, name in enumerate(kind.internal)]
        if kind.n_internal is not None:
            named.append((f"S_{prefix}_BLOCKS", len(HEADER) + len(kind.internal)))
    offsets: dict[str, int] = {}
    for name, value in named:
        if name in offsets:  # kinds sharing a prefix (maxwell, maxwell_bank) could clash
            raise ValueError(f"{name} names two slots; rename one of them in droptower.rheology.kinds")
        offsets[name] = value
    return offsets


def render() -> str:
    """The generated block of ``kernels.py``, marker lines included."""
    lines = [BEGIN, "# from droptower.rheology.kinds by `python -m droptower.rheology.slots`: do not edit by hand"]
    lines += [f"{name} = {value}" for name, value in slot_offsets().items()]
    return "\n".join([*lines, END])


def _split(text: str) -> tuple[str, str, str]:
    start, stop = text.index(BEGIN), text.index(END) + len(END)
    return text[:start], text[start:stop], text[stop:]


def current_block(path: Path = KERNELS_PY) -> str:
    """The block as it stands in ``kernels.py``."""
    return _split(path.read_text(encoding="utf-8"))[1]


def write(path: Path = KERNELS_PY) -> bool:
    """Rewrite the block in ``kernels.py`` from the records; return whether it changed."""
    head, block, tail = _split(path.read_text(encoding="utf-8"))
    new = render()
    if block == new:
        return False
    path.write_text(head + new + tail, encoding="utf-8")
    return True


if __name__ == "__main__":
    print(f"{KERNELS_PY}: {'rewritten' if write() else 'already in sync'}")
