"""The study: its configuration files merged once, and the one frozen :class:`Study` that
answers "the parameters of this plane / sweep / command line, and where each value came from".

``config/config.yaml`` and the files merged over it (layout and defaults in
``workflow/schemas/config.schema.yaml``, described in docs/pipeline.md) are checked by the
workflow before any job (``workflow/rules/common.smk``) and by the ``gearsim`` CLI with the same
code (:func:`load_config`; the schema and the other checks: :mod:`gearsim.study.schema`), so a
bad key fails with one line that names it, never a traceback. The model parameters a
configuration simulates (standard-parameter file or gear file, then ``parameters``, then a
plane's or sweep's ``fixed``, then a command line's values) are resolved by
:meth:`Study.parameters` only.
"""

from __future__ import annotations

import copy
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.errors import ConfigError
from gearsim.numerics.device import Execution
from gearsim.numerics.settings import IntegrationSettings, Method
from gearsim.safe_yaml import load_mapping
from gearsim.study.config_io import load_standard_parameters
from gearsim.study.schema import check_config, project_root, validate_schema

# IntegrationSettings: the type of the `integration:` section, for readers above the numerics
__all__ = ["ConfigError", "IntegrationSettings", "Parameters", "Study", "project_root"]

DEFAULT_CONFIG = "config/config.yaml"
DEFAULT_STANDARD_PARAMETERS = "config/standard_parameters.yaml"
#: Environment variable naming the study directory of workflow jobs (see :func:`study_root`).
STUDY_ROOT_ENV = "GEARSIM_STUDY_ROOT"
#: What a study file replaces instead of merging (:func:`merge_study`).
STUDY_KEYS = ("planes", "sweeps", "points")


# ---------------------------------------------------------------------------------- merging
def merge(base: dict, update: Mapping) -> dict:
    """Recursive update (Snakemake's semantics for config files given with --configfile)."""
    for key, value in update.items():
        if isinstance(value, Mapping) and isinstance(base.get(key), dict):
            merge(base[key], value)
        else:
            base[key] = copy.deepcopy(value)
    return base


def merge_study(config: dict, doc: Mapping) -> dict:
    """Merge one config file (or ``--config`` overrides) over ``config``.

    Snakemake's rule (recursive update), with one addition: a document that names a ``study``
    starts its own ``planes``, ``sweeps`` and ``points`` (those merged before it are dropped), so
    a study file runs only what it lists. Snakemake's own merge is redone this way in
    ``workflow/rules/common.smk``.
    """
    if doc.get("study") is not None:
        for key in STUDY_KEYS:
            config[key] = {}
    return merge(config, doc)


def load_config(
    paths: str | Path | Iterable[str | Path],
    overrides: Mapping | None = None,
    root: str | Path | None = None,
) -> dict:
    """Merge config files in order (later wins, recursively; :func:`merge_study`), validate and
    fill defaults; the parameters of the study, each plane and each sweep are resolved once to
    check them. Relative paths inside are resolved against ``root`` (:func:`study_root`)."""
    if isinstance(paths, (str, Path)):
        paths = [paths]
    config: dict = {}
    for p in paths:
        try:
            doc = load_mapping(p, "config file")
        except ParameterError as exc:
            raise ConfigError(str(exc)) from None
        merge_study(config, doc)
    if overrides:
        if not isinstance(overrides, Mapping):
            raise ConfigError("config overrides must be a mapping of keys")
        merge_study(config, overrides)
    validate_schema(config)
    check_config(config, study_root(root))
    Study(config, study_root(root))  # the parameter set of the study, of each plane and sweep
    return config


def study_root(root: str | Path | None = None) -> Path:
    """The directory a study runs in: ``root``; else ``$GEARSIM_STUDY_ROOT`` (set by the
    workflow for its jobs); else the working directory when it holds ``config/config.yaml``
    (Snakemake's working directory); else the source checkout."""
    if root is not None:
        return Path(root)
    env = os.environ.get(STUDY_ROOT_ENV)
    if env:
        return Path(env)
    cwd = Path.cwd()
    if (cwd / DEFAULT_CONFIG).is_file():
        return cwd
    return project_root()


def study_config(
    configfiles: Iterable[str | Path] = (),
    overrides: Mapping | None = None,
    root: str | Path | None = None,
) -> dict:
    """The study's configuration as the pipeline sees it: ``config/config.yaml`` of
    :func:`study_root`, then ``configfiles`` merged over it in order (as ``snakemake
    --configfile``), then ``overrides`` (as ``snakemake --config``).

    This is the one resolution of "the study's defaults": the CLI, the Python API
    (:meth:`Study.load`) and the workflow use it.
    """
    base = study_root(root) / DEFAULT_CONFIG
    if not base.is_file():
        raise ConfigError(f"{base}: the study's configuration is missing")
    paths = [base]
    for p in configfiles:
        if Path(p).resolve() != base.resolve():
            paths.append(Path(p))
    return load_config(paths, overrides, root=study_root(root))


# ------------------------------------------------------------------------------- the study
def standard_parameters_path(config: Mapping, root: str | Path | None = None) -> Path | None:
    """The standard-parameter file of ``config`` (relative to :func:`study_root`), or ``None``
    for an explicit ``standard_parameters: null`` (the built-in ModelParameters defaults)."""
    sp = config.get("standard_parameters", DEFAULT_STANDARD_PARAMETERS)
    if sp is None:
        return None
    path = Path(sp)
    return path if path.is_absolute() else study_root(root) / path


@dataclass(frozen=True)
class Parameters:
    """A resolved parameter set: the values, one line saying where they came from (recorded in
    every result's provenance), and the origin of each value."""

    model: ModelParameters
    source: str
    origin: Mapping[str, str]


def _base_values(config: Mapping, root: Path) -> tuple[dict[str, Any], str]:
    """The values of the study's gear file or standard-parameter file (or the built-in
    defaults for ``standard_parameters: null``) and that file's name."""
    path = standard_parameters_path(config, root)
    if config.get("gear"):  # a gear file replaces the standard parameters (docs/units.md)
        from gearsim.physical.units import config_gear

        try:
            values = config_gear(config, root).to_model_parameters().to_dict()
        except ParameterError as exc:
            raise ConfigError(str(exc)) from None
        return values, f"gear file {config['gear']}"
    if path is None:
        return {}, "builtin-defaults"
    try:
        values = dict(load_standard_parameters(path))
    except ParameterError as exc:
        raise ConfigError(
            f"config key 'standard_parameters': {exc} (standard_parameters: null means the "
            "built-in defaults)"
        ) from None
    return values, str(config.get("standard_parameters", DEFAULT_STANDARD_PARAMETERS))


@dataclass(frozen=True)
class Study:
    """A study's configuration, merged and validated once (:meth:`load`), and the answers read
    off it. Frozen: a changed study is a new one (:meth:`with_parameters`).

    ``config`` is read-only (a mapping proxy over a private copy; :meth:`config_dict` gives a
    copy to write); ``root`` the directory relative paths are resolved against;
    ``settings`` the integration settings of every simulation of the study; ``execution``
    where its simulating jobs run (the ``execution`` section; outside every settings hash).
    """

    config: Mapping[str, Any]
    root: Path
    settings: IntegrationSettings = field(init=False)
    execution: Execution = field(init=False)
    _base: tuple[dict[str, Any], str] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        config = copy.deepcopy(dict(self.config))
        object.__setattr__(self, "config", MappingProxyType(config))
        object.__setattr__(self, "root", Path(self.root))
        object.__setattr__(self, "settings", integration_settings(config))
        object.__setattr__(self, "execution", Execution(**(config.get("execution") or {})))
        object.__setattr__(self, "_base", _base_values(config, self.root))
        for kind, key in (("planes", "plane"), ("sweeps", "sweep")):
            for name in config.get(kind) or {}:
                try:
                    self.parameters(**{key: name})
                except ParameterError as exc:
                    raise ConfigError(f"config key '{kind}.{name}': {exc}") from None
        try:
            self.parameters()
        except ParameterError as exc:
            raise ConfigError(f"config key 'parameters': {exc}") from None

    @classmethod
    def load(cls, configfiles: Iterable[str | Path] = (), overrides: Mapping | None = None,
             root: str | Path | None = None) -> Study:
        """The study as the pipeline sees it (:func:`study_config`: ``config/config.yaml`` of
        :func:`study_root`, the ``configfiles`` merged over it, then ``overrides``)."""
        return cls(study_config(configfiles, overrides, root), study_root(root))

    @classmethod
    def of(cls, config: Mapping, root: str | Path | None = None) -> Study:
        """The study of a configuration that :func:`load_config` gave (merged and checked)."""
        return cls(config, study_root(root))

    def config_dict(self) -> dict[str, Any]:
        """A writable copy of the configuration."""
        return copy.deepcopy(dict(self.config))

    def parameters(self, *, plane: str | None = None, sweep: str | None = None,
                   changes: Mapping[str, Any] | None = None, words: str = "",
                   **values: Any) -> Parameters:
        """The parameter set of the study, of one of its planes or sweeps (its ``fixed`` on
        top), with ``changes`` and ``values`` last (a command line's or a caller's own values;
        ``words`` say where they came from in the source line, default "changes").

        ``origin`` names, per parameter, the file, ``parameters``, ``planes.<plane>.fixed``,
        ``sweeps.<sweep>.fixed``, the ``words`` or ``default`` (``ModelParameters``'s). A plane's
        axes and a sweep's swept value are set per cell by the caller.
        """
        base, source = self._base
        merged: dict[str, Any] = dict(base)
        origin = dict.fromkeys(ModelParameters.names(), "default")
        origin.update(dict.fromkeys(base, source))
        extra = dict(self.config.get("parameters") or {})
        if extra:
            source += " + parameters " + ", ".join(f"{k}={v}" for k, v in sorted(extra.items()))
        layers = [(extra, "parameters")]
        if plane is not None:
            layers.append((self.config["planes"][plane].get("fixed") or {},
                           f"planes.{plane}.fixed"))
        if sweep is not None:
            layers.append((self.config["sweeps"][sweep].get("fixed") or {},
                           f"sweeps.{sweep}.fixed"))
        given = {**(changes or {}), **values}
        layers.append((given, words or "changes"))
        for layer, where in layers:
            merged.update(layer)
            origin.update(dict.fromkeys(layer, where))
        if words:
            source += " + " + words
        return Parameters(ModelParameters.from_mapping(merged), source,
                          MappingProxyType(origin))

    def with_parameters(self, values: Mapping[str, Any]) -> Study:
        """This study with ``values`` folded into its ``parameters`` (what a command's own
        values make of the study in its records)."""
        config = self.config_dict()
        config["parameters"] = {**(config.get("parameters") or {}), **values}
        return Study(config, self.root)

    def with_device(self, device: str | None) -> Study:
        """This study with its jobs run on ``device`` (a command's ``--device``; None: as it
        is)."""
        if device is None or device == self.execution.device:
            return self
        config = self.config_dict()
        config["execution"] = {**(config.get("execution") or {}), "device": device}
        return Study(config, self.root)


def settings_text(settings: IntegrationSettings) -> str:
    """One line describing integration settings (printed and saved beside every result)."""
    if settings.method is Method.RK4:
        how = f"rk4 {settings.steps_per_period} steps/period"
    else:
        how = f"dp5 rtol={settings.rtol:g} atol={settings.atol:g}"
    return (
        f"{how}, hmax={settings.hmax:g}, transient {settings.transient} periods "
        f"({settings.transient_continuation} on continuation), up to {settings.max_periods} "
        f"measured, n_max={settings.n_max}"
    )


def run_folder(config: Mapping) -> str | None:
    """The folder under ``studies/`` a run works in: its ``study``, else its ``folder`` (a
    variant of the paper's study that keeps its own results, e.g. config/quick.yaml); None for
    the project directory itself."""
    return config.get("study") or config.get("folder")


def results_dir(config: Mapping) -> Path:
    """Where a study's results go: ``results`` for the default study, else
    ``studies/<folder>/results`` (:func:`run_folder`; logs beside it)."""
    folder = run_folder(config)
    return Path("results") if folder is None else Path("studies", folder, "results")


def logs_dir(config: Mapping) -> Path:
    """Where a study's logs go (``logs`` or ``studies/<folder>/logs``)."""
    folder = run_folder(config)
    return Path("logs") if folder is None else Path("studies", folder, "logs")


def orbit_tables(config) -> list[str]:
    """The continuation tables the pipeline makes for a config (workflow/rules/orbits.smk):
    ``standard`` (config ``orbits.continuation`` and a sweep named ``standard``) and
    ``<plane>_curves`` for every plane (``orbits.curves``)."""
    opts = dict(config.get("orbits") or {})
    out = []
    if opts.get("continuation", True) and "standard" in (config.get("sweeps") or {}):
        out.append("standard")
    if opts.get("curves", True):
        out += [f"{plane}_curves" for plane in (config.get("planes") or {})]
    return out


def integration_settings(config: Mapping) -> IntegrationSettings:
    """The :class:`~gearsim.cell.simulate.IntegrationSettings` of ``config['integration']``."""
    return IntegrationSettings(**(config.get("integration") or {}))


