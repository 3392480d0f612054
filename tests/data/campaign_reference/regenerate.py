"""Regenerate the campaign reference values (``results.json``) with the code as it stands:

    python tests/data/campaign_reference/regenerate.py

Runs the 36-test plan ``doe.toml`` with ``coupling.toml`` on the shipped ``rapp2022`` rig (every
campaign setting at its default) and stores, per test, its status and every extracted number.
``tests/test_campaign_reference.py`` compares a fresh campaign against them. Regenerate only
when a change of the physics or of the extraction is meant to move the results (say which in
the commit); a change of speed or of the log's container must leave them within tolerance.
"""
from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent


def campaign_values(out: Path, **settings) -> list[dict]:
    """Per test of the reference plan: test_id, seed, status, flags and every numeric result."""
    from droptower.campaign import run_campaign

    run = run_campaign(out, "rapp2022", HERE / "coupling.toml", HERE / "doe.toml", progress=False, **settings)
    rows = []
    for row in run.results.sort_values("test_id").to_dict(orient="records"):
        values = {k: float(v) for k, v in row.items()
                  if isinstance(v, float) and k not in ("inertia_kgm2", "drop_mass_kg", "drop_height_m", "preload_nm")}
        rows.append({"test_id": int(row["test_id"]), "seed": int(row["seed"]), "status": row["status"],
                     "flags": list(row["flags"]) if isinstance(row["flags"], (list, tuple)) else row["flags"],
                     "values": {k: (v if math.isfinite(v) else None) for k, v in values.items()}})
    return rows


def main() -> None:
    from droptower import __version__

    with tempfile.TemporaryDirectory() as tmp:
        rows = campaign_values(Path(tmp) / "campaign", workers=1)
    (HERE / "results.json").write_text(json.dumps({"droptower": __version__, "tests": rows}, indent=1) + "\n")
    print(f"wrote {HERE / 'results.json'}: {len(rows)} tests")


if __name__ == "__main__":
    main()
