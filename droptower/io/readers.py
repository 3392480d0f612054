"""One entry point for every log format: :func:`read_any` picks the reader.

By suffix, then by content: ``.bin`` catman binary (checked by its file ID); ``.parquet``
droptower log or generic Parquet (by its schema metadata); ``.mf4``/``.mdf`` MDF4;
``.tdms`` TDMS; anything else is text: a droptower log if it starts with
``# droptower-log``, else CSV/ASCII (catman ASCII, MTS 793 ``.dat``, plain CSV).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from droptower.errors import DroptowerError, readable_file, unreadable_file
from droptower.io.channels import Record

#: options :func:`read_any` passes to the CSV/ASCII reader (ignored by binary formats).
CSV_OPTIONS = ("delimiter", "decimal", "header_lines", "unit_row", "encoding", "invalid_marker")


def read_any(path: str | Path, **options: Any) -> Record:
    """Read any supported log file into a :class:`Record`.

    options: CSV/ASCII settings (:data:`CSV_OPTIONS`, see
    :func:`droptower.io.csvfmt.read_csv_log`); None values mean "sniff".
    """
    path = Path(path)
    unknown = set(options) - set(CSV_OPTIONS)
    if unknown:
        raise DroptowerError(f"unknown reader option(s): {', '.join(sorted(unknown))}", file=path)
    readable_file(path)
    suffix = path.suffix.lower()
    if suffix == ".bin":
        from droptower.io.catman import is_catman, read_catman

        if not is_catman(path):
            raise DroptowerError("not a catman binary file (unknown file ID)", file=path)
        return read_catman(path)
    if suffix == ".parquet":
        from droptower.io.droptower_log import parquet_metadata, read_log
        from droptower.io.parquetfmt import read_parquet

        try:
            is_log = parquet_metadata(path) is not None
        except Exception as exc:  # pyarrow's errors for a non-Parquet file vary
            raise unreadable_file(path, exc, "Parquet file") from None
        return read_log(path) if is_log else read_parquet(path)
    if suffix in (".mf4", ".mdf", ".dat") and _is_mdf(path):
        from droptower.io.mdf import read_mdf

        return read_mdf(path)
    if suffix in (".mf4", ".mdf"):
        raise DroptowerError("not an MDF file (no MDF identification block)", file=path)
    if suffix == ".tdms":
        from droptower.io.tdms import read_tdms

        return read_tdms(path)
    from droptower.io.catman import is_catman

    if is_catman(path):
        from droptower.io.catman import read_catman

        return read_catman(path)
    from droptower.io.droptower_log import is_droptower_csv, read_log

    if is_droptower_csv(path):
        return read_log(path)
    from droptower.io.csvfmt import read_csv_log

    return read_csv_log(path, **{k: v for k, v in options.items() if v is not None})


def _is_mdf(path: Path) -> bool:
    """MDF files start with ``MDF     `` (MDF 3/4) or ``UnFinMF `` (unfinalised MDF 4)."""
    with open(path, "rb") as fh:
        head = fh.read(8)
    return head in (b"MDF     ", b"UnFinMF ")
