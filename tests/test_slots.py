"""The kernels index their slices by the slot names of droptower.rheology.kinds, never by number.

kernels.py carries a block of named slot offsets generated from the kinds' records
(droptower.rheology.slots); these tests check that block against the records, that every
constant names a slot of its record, and that no literal slot offset is left in the kernels.
"""
from __future__ import annotations

import re
import shutil
import tokenize

import pytest

from droptower.rheology import kernels as K
from droptower.rheology import kinds, slots

#: forms of a literal slot offset: s[so + 3], p[po + 1 + n], eo = so + 6, p[po], pv[5], the
#: header read through the state offsets of a coupling (s_off[e] + 1)
LITERAL_SLOT = re.compile(r"\b(?:so|po)\s*\+\s*\d|\[\s*(?:so|po)\s*\]|\bpv?\s*\[\s*\d|s_off\s*\[\s*\w+\s*\]\s*\+\s*\d")


def _kernel_code_lines() -> list[str]:
    """The kernels' code, line by line, without docstrings and comments (they may quote p[po])."""
    lines: dict[int, list[str]] = {}
    with tokenize.open(slots.KERNELS_PY) as f:
        for tok in tokenize.generate_tokens(f.readline):
            if tok.type not in (tokenize.STRING, tokenize.COMMENT):
                lines.setdefault(tok.start[0], []).append(tok.string)
    return [" ".join(words) for _, words in sorted(lines.items())]


def test_the_generated_block_matches_the_records():
    assert slots.current_block() == slots.render(), (
        "kernels.py's slot offsets are stale: python -m droptower.rheology.slots")


def test_every_slot_constant_is_the_slot_its_record_names():
    for i, name in enumerate(kinds.HEADER):
        assert getattr(K, f"S_{name.upper()}") == i
    assert K.N_HEADER == len(kinds.HEADER)
    expected = {"N_HEADER"} | {f"S_{name.upper()}" for name in kinds.HEADER}
    for record in kinds.KINDS.values():
        prefix = record.name.upper()
        for name in record.params:
            assert getattr(K, f"P_{prefix}_{name.upper()}") == record.param_slot(name)
            expected.add(f"P_{prefix}_{name.upper()}")
        for name in record.internal:
            assert getattr(K, f"S_{prefix}_{name.upper()}") == record.state_slot(name)
            expected.add(f"S_{prefix}_{name.upper()}")
        if record.n_params is not None:  # the tables follow the named slots
            assert getattr(K, f"P_{prefix}_TABLES") == len(record.params)
            expected.add(f"P_{prefix}_TABLES")
        if record.n_internal is not None:  # the repeated blocks follow the header and named slots
            assert getattr(K, f"S_{prefix}_BLOCKS") == K.N_HEADER + len(record.internal)
            expected.add(f"S_{prefix}_BLOCKS")
    # no slot constant in the kernels that no record names (a hand-written offset)
    constants = {n for n in vars(K) if re.fullmatch(r"[PS]_[A-Z0-9_]+|N_HEADER", n)}
    assert constants == expected == set(slots.slot_offsets())


def test_two_slots_under_one_name_are_refused(monkeypatch):
    # maxwell and maxwell_bank share a prefix: maxwell's slot "bank_n" would be P_MAXWELL_BANK_N too
    record = kinds.KINDS[K.MAXWELL]
    monkeypatch.setitem(kinds.KINDS, K.MAXWELL, kinds.KernelKind(**{**record.__dict__, "params": ("k", "c", "bank_n")}))
    with pytest.raises(ValueError, match="P_MAXWELL_BANK_N names two slots"):
        slots.slot_offsets()


def test_no_literal_slot_offset_is_left_in_the_kernels():
    for sample in ("s[so + 3]", "p[po + 1 + n]", "eo = so + 6", "n = int(p[po])", "pv[5] > 0", "sb[s_off[e] + 1]"):
        assert LITERAL_SLOT.search(sample), sample  # the scan sees every form
    for sample in ("s[so + S_TORQUE_NM]", "p[ko + i]", "pv[P_VARIABLE_MAXWELL_NK]", "p[off:off + nc]"):
        assert not LITERAL_SLOT.search(sample), sample
    code = _kernel_code_lines()
    assert any("S_TORQUE_NM" in line for line in code)  # the scan reads the kernels' code
    found = [line for line in code if LITERAL_SLOT.search(line)]
    assert not found, f"literal slot offsets in kernels.py: {found}"


def test_regeneration_rewrites_a_stale_block_and_only_it(tmp_path):
    copy = tmp_path / "kernels.py"
    shutil.copy(slots.KERNELS_PY, copy)
    original = copy.read_text(encoding="utf-8")
    assert slots.write(copy) is False  # in sync: untouched
    copy.write_text(original.replace("S_PAYNE_CACHED_H = 13", "S_PAYNE_CACHED_H = 12"), encoding="utf-8")
    assert slots.write(copy) is True
    assert copy.read_text(encoding="utf-8") == original


def test_a_renamed_slot_makes_the_block_stale(monkeypatch):
    record = kinds.KINDS[K.MAXWELL]
    renamed = kinds.KernelKind(**{**record.__dict__, "internal": ("spring_elongation_rad", *record.internal[1:])})
    monkeypatch.setitem(kinds.KINDS, K.MAXWELL, renamed)
    with pytest.raises(AssertionError):
        test_the_generated_block_matches_the_records()
