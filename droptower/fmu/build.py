"""Write a coupling as an FMI 2.0 co-simulation FMU with pythonfmu (model: :mod:`.slave`)."""
from __future__ import annotations

import json
import shutil
import tempfile
from pathlib import Path

from droptower.errors import DroptowerError, WriteError
from droptower.rates import RIG_SAMPLE_RATE_HZ
from droptower.rheology.coupling import Coupling

#: the default internal step: the rig's sample rate (Rapp et al. 2022)
DEFAULT_STEP_S = 1.0 / RIG_SAMPLE_RATE_HZ


def coupling_data(coupling: Coupling) -> dict:
    """The coupling file's content (its first parameter set) as plain data."""
    import tomllib

    from droptower.rheology.loader import coupling_to_toml

    return tomllib.loads(coupling_to_toml(coupling))


def build_fmu(coupling: Coupling, out: str | Path, internal_step_s: float = DEFAULT_STEP_S) -> Path:
    """Write ``coupling`` as the FMU ``out`` (``.fmu``); internal_step_s: the largest internal
    time step in s. The FMU holds the model script, the coupling's elements and pythonfmu's
    FMI wrapper binaries (Linux x86-64, Windows x64); it runs where a Python with pythonfmu and
    droptower is installed."""
    try:
        from pythonfmu.builder import FmuBuilder
    except ImportError:
        raise DroptowerError("building an FMU needs pythonfmu: pip install 'droptower[fmu]'") from None
    out = Path(out)
    if out.suffix.lower() != ".fmu":
        raise DroptowerError("the FMU's file name must end in .fmu", file=out)
    if not (0 < internal_step_s <= 1.0):
        raise DroptowerError(f"the internal step must be > 0 and at most 1 s, got {internal_step_s:g}")
    if coupling.n_sets != 1:
        raise DroptowerError(f"an FMU holds one coupling, this one has {coupling.n_sets} parameter sets")
    with tempfile.TemporaryDirectory(prefix="droptower_fmu_") as work:
        work_dir = Path(work)
        script = work_dir / "droptower_coupling.py"
        shutil.copyfile(Path(__file__).with_name("slave.py"), script)
        spec = work_dir / "coupling.json"
        spec.write_text(json.dumps({"coupling": coupling_data(coupling), "internal_step_s": internal_step_s}))
        built = work_dir / "DroptowerCoupling.fmu"
        FmuBuilder.build_FMU(script, dest=built, project_files=[spec], needsExecutionTool="true",
                             canHandleVariableCommunicationStepSize="true", canGetAndSetFMUstate="false")
        try:
            out.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(built, out)
        except OSError as exc:
            out.unlink(missing_ok=True)
            raise WriteError(f"cannot write ({exc.strerror or exc})", file=out) from None
    return out
