"""A coupling model from drop-test logs alone, as one call: read the campaign, fit, write.

:func:`read_drop_tests` reads the logs (files, folders, campaign folders) into free decays with
the settings a fit needs (the rig's lever, sensor radius, inertia and preload conditioning where
a rig is named); :func:`identify_from_drop_tests` fits a family to them
(:func:`~droptower.identify.dropfit.identify_drops`) and returns the
:class:`~droptower.identify.result.Identification` (whose
:meth:`~droptower.identify.result.Identification.write_coupling` writes the fitted coupling). The ``identify`` command is a thin layer over these for drop tests.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping

from droptower.deprecation import renamed_keywords
from droptower.errors import DroptowerError
from droptower.identify.dropfit import FIT_OPTIONS, HOLDOUT_FRACTION, DropFitSettings, identify_drops
from droptower.identify.droplogs import DropDecay, ReadSettings, read_decays
from droptower.identify.result import Identification, Parameters

#: What ``initial_rate`` may be: where the decay's initial rate comes from.
INITIAL_RATES = ("auto", "impulse", "slope")


@dataclass
class DropCampaign:
    """Drop-test logs read for an identification.

    decays: the usable tests' free decays; excluded: the others as {file, reason}; settings:
    the fit's (:class:`~droptower.identify.dropfit.DropFitSettings`); options: the family's
    options left after the fit's and the reading's were taken out; read: how the logs were
    read; paths: the log files found.
    """

    decays: list[DropDecay]
    excluded: list[dict[str, str]]
    settings: DropFitSettings
    options: dict[str, Any]
    read: ReadSettings
    paths: list[str] = field(default_factory=list)

    def __repr__(self) -> str:
        return f"<DropCampaign: {len(self.decays)} usable drop test(s), {len(self.excluded)} excluded>"


def log_paths(data: Iterable[str | Path]) -> list[Path]:
    """The files named by ``data``: files as they are, a folder's files (a campaign folder's ``logs/``)."""
    files = []
    for p in map(Path, [data] if isinstance(data, (str, Path)) else data):
        logs = p / "logs" if (p / "logs").is_dir() else p
        files += sorted(logs.iterdir()) if p.is_dir() else [p]
    return files


@renamed_keywords(model="family")
def read_drop_tests(data: str | Path | Iterable[str | Path], *, family: str | None = None,
                    options: Mapping[str, Any] | None = None, template: str | None = None,
                    holdout_fraction: float = HOLDOUT_FRACTION, rig: Any = None, inertia_kgm2: float | None = None,
                    lever_length_m: float | None = None, roles: Mapping[str, str] | None = None,
                    sensor_radius_m: float | None = None, conditions: Any = None) -> DropCampaign:
    """Read drop-test logs for an identification.

    Parameters
    ----------
    data : str, path or list
        Log files, folders of logs or campaign folders.
    family : str, optional
        The family to be fitted (``template`` needs ``template``; ``model`` in release 0.1:
        deprecated).
    options : dict, optional
        The family's options; the fit's (``substeps``, ``torque_weight``, ``max_nfev``,
        ``seed``, ``conditioning``) and the reading's (``cycles``: periods compared after the
        impact; ``initial_rate``: auto, impulse or slope) are taken out.
    template : str, optional
        The coupling (preset name or TOML) whose structure ``template`` fits.
    holdout_fraction : float
        Share of the tests held out and predicted.
    rig : str or RigConfig, optional
        Rig TOML, preset or :class:`~droptower.rig.config.RigConfig`: its lever length (m),
        sensor radius (m), inertia (kg*m^2, when it has one lever fixture) and preload
        conditioning fill what the logs do not say.
    inertia_kgm2 : float, optional
        Override of the logs' inertia (kg*m^2).
    lever_length_m : float, optional
        Override of the logs' lever length (m).
    roles : dict, optional
        Channel role -> ``NAME[:UNIT]`` (e.g. ``{"angle": "Winkel:deg"}``).
    sensor_radius_m : float, optional
        Laser spot radius (m) for a distance channel, over the logs' and the rig's.
    conditions : Conditions, optional
        Per-file test conditions (:class:`~droptower.io.conditions.Conditions`): each log's
        fixture or inertia, drop mass and height, preload, temperature.

    Returns
    -------
    DropCampaign
        The decays, the excluded logs with their reasons, and the settings.
    """
    options = dict(options or {})
    if template is not None:
        options["template"] = template
    if family == "template" and "template" not in options:
        raise DroptowerError("`family=template` needs `template` (a preset name or a coupling TOML)")
    defaults: dict[str, float] = {}
    conditioning: tuple[float, float] | None = DropFitSettings.conditioning
    fixtures = None
    if rig is not None:
        from droptower.rig.config import RigConfig, load_rig

        config = rig if isinstance(rig, RigConfig) else load_rig(rig)
        defaults["lever_length_m"] = config.lever_length_m
        defaults["sensor_radius_m"] = config.sensors.laser.radius_m
        if len(config.inertias_kgm2) == 1:
            defaults["inertia_kgm2"] = config.inertias_kgm2[0]
        else:
            named = getattr(config, "fixtures", None) or {}
            fixtures = ", ".join(f"{n} {j:g} kg*m^2" for n, j in named.items()) if named else (
                ", ".join(f"{j:g}" for j in config.inertias_kgm2) + " kg*m^2")
        conditioning = (config.simulation.preload_ramp_s, config.simulation.preload_hold_s)
    fit_opts = {k: options.pop(k) for k in list(options) if k in FIT_OPTIONS}
    options.pop("skip_s", None)
    cycles = float(options.pop("cycles", 3.0))
    rate = str(options.pop("initial_rate", "auto"))
    if rate not in INITIAL_RATES:
        raise DroptowerError(f"option initial_rate must be {', '.join(INITIAL_RATES[:-1])} or {INITIAL_RATES[-1]}, "
                             f"got {rate!r}")
    if not fit_opts.pop("conditioning", True):
        conditioning = None
    settings = DropFitSettings(substeps=int(fit_opts.get("substeps", 1)),
                               torque_weight=float(fit_opts.get("torque_weight", 0.5)), conditioning=conditioning,
                               holdout_fraction=holdout_fraction, max_nfev=int(fit_opts.get("max_nfev", 0)),
                               seed=int(fit_opts.get("seed", 0)))
    extra = {"conditions": conditions} if conditions is not None else {}  # LogSettings merges them per file
    read = ReadSettings(roles=dict(roles or {}), inertia_kgm2=inertia_kgm2, lever_length_m=lever_length_m,
                        defaults=defaults, sensor_radius_m=sensor_radius_m, cycles=cycles, rate=rate,
                        rig_fixtures=fixtures if inertia_kgm2 is None else None, **extra)
    paths = [data] if isinstance(data, (str, Path)) else list(data)
    decays, excluded = read_decays(paths, read)
    return DropCampaign(decays, excluded, settings, options, read, [str(p) for p in log_paths(paths)])


@renamed_keywords(model="family")
def identify_from_drop_tests(data: DropCampaign | str | Path | Iterable[str | Path], family: str, *,
                             init: Mapping[str, float] | Parameters | None = None,
                             bounds: Mapping[str, tuple[float, float]] | None = None,
                             options: Mapping[str, Any] | None = None, template: str | None = None,
                             holdout_fraction: float = HOLDOUT_FRACTION, rig: Any = None,
                             inertia_kgm2: float | None = None, lever_length_m: float | None = None,
                             roles: Mapping[str, str] | None = None, sensor_radius_m: float | None = None,
                             conditions: Any = None) -> Identification:
    """Identify a coupling model from drop-test logs alone.

    Parameters
    ----------
    data : paths or DropCampaign
        Log files, folders or campaign folders, or a :class:`DropCampaign` already read (then
        the reading's parameters below do not apply).
    family : str
        The family (:data:`~droptower.identify.dropfit.DROP_FAMILIES`; ``model`` in release 0.1:
        deprecated).
    init : dict or Parameters, optional
        Held values or parameters, as for :func:`~droptower.identify.dropfit.identify_drops`.
    bounds : dict, optional
        Bounds by parameter name, as there.
    options : dict, optional
        The family's options and the fit's and the reading's (see :func:`read_drop_tests`).
    template : str, optional
        With ``family="template"``: the coupling (preset or TOML) whose structure is fitted.
    holdout_fraction : float
        Share of the tests held out and predicted.
    rig : str or RigConfig, optional
        Rig TOML or preset (lever length, sensor radius, a single inertia, conditioning).
    inertia_kgm2 : float, optional
        Lever inertia (kg*m^2), overriding the logs'.
    lever_length_m : float, optional
        Lever length (m), overriding the logs'.
    roles : dict, optional
        Channel role -> ``NAME[:UNIT]``.
    sensor_radius_m : float, optional
        Laser spot radius (m) for a distance channel.
    conditions : Conditions, optional
        Per-file test conditions (each log's inertia or fixture, drop mass and height, ...).

    Returns
    -------
    Identification
        From :data:`~droptower.identify.result.DROPS`: parameters, angle errors of the fitting
        and held-out tests, verdict, coupling.

    Examples
    --------
    >>> result = identify_from_drop_tests("runs/table2", "zerodim6", rig="rapp2022")  # doctest: +SKIP
    >>> result.params.to_frame()  # doctest: +SKIP
    """
    if isinstance(data, DropCampaign):
        campaign = data
    else:
        campaign = read_drop_tests(data, family=family, options=options, template=template,
                                   holdout_fraction=holdout_fraction, rig=rig, inertia_kgm2=inertia_kgm2,
                                   lever_length_m=lever_length_m, roles=roles, sensor_radius_m=sensor_radius_m,
                                   conditions=conditions)
    return identify_drops(family, campaign.decays, excluded=campaign.excluded, settings=campaign.settings,
                          init=init, bounds=bounds, options=campaign.options)
