"""pino_mbd: pino-mbd in Python, in-process.

Describe a multi-body system (``System.load``), run the exact solver on a table of designs
(``System.simulate``), predict with a trained neural-operator model and its calibrated
intervals (``Model.load``, ``Model.predict``, ``Model.indices``) or with the system's surrogate,
each index from its most accurate model (``Surrogate.load``, the same calls), drive the whole pipeline
(``Pipeline``) and run a design study (``study``). The work is done by the Rust libraries of
pino-mbd (the same code as the command-line stages, so the same numbers, bit for bit) with the
GIL released; tables go in as polars or pandas DataFrames, pyarrow tables or dicts of arrays,
and come back as polars DataFrames (``.to_pandas()`` for pandas), through the Arrow C stream
interface without copies.

Units are SI throughout (m, s, N, kg, rad) unless a column's unit says otherwise; the unit of
every column is in ``System.columns`` and in the ``units`` of the native result.

Every refusal (a description's problem with its ``file:line``, an unknown parameter, a
non-finite value, a wrong shape, a model of another system) raises ``PinoError``, a
``ValueError`` naming the argument and field at fault (``designs.k_s[1]``, ``values.k_q``,
``excitation``).

An excitation (the ``excitation`` argument of ``System.simulate`` and of ``predict`` and
``indices`` of ``Model`` and ``Surrogate``) is one of: a seed (an ``int`` >= 0, short for ``{"seed": N}``);
``{"seed": N, "dx": m, "length": m}``, profiles generated as the ``irregularity`` stage
generates them (``dx`` and ``length`` optional: a model's default to its dataset's, the
solver's to 0.1 m and a length that covers the run); or a profile table (``sample_id``, ``x``
and ``eta`` in m, ``profile`` with several generated profiles: the ``irregularity`` artifact)
as a DataFrame, a pyarrow table or a Parquet file's path. A design row's ``sample_id`` names
its stream (generated) or sample (table).
"""

from __future__ import annotations

import json
import os
import warnings
from collections.abc import Mapping, Sequence
from typing import Any, Union

import numpy as np
import polars as pl

from . import _pino_mbd as _native
from ._pino_mbd import PinoError, __version__

__all__ = ["PinoError", "System", "Model", "Surrogate", "Pipeline", "study", "__version__"]

PathLike = Union[str, "os.PathLike[str]"]
# A seed, {"seed": N, "dx": m, "length": m}, a profile table or its Parquet file (module doc).
Excitation = Union[int, Mapping[str, float], PathLike, Any, None]


def _designs(obj: Any, what: str = "designs") -> Any:
    """A table with ``__arrow_c_stream__`` from a DataFrame, a pyarrow table or a dict of
    1-D arrays (or scalars: one design); wrong shapes raise ``PinoError`` naming the column."""
    if obj is None:
        raise PinoError(f"{what}: missing (a DataFrame or a dict of arrays, one row per design)")
    if hasattr(obj, "__arrow_c_stream__"):
        return obj
    if isinstance(obj, Mapping):
        cols: dict[str, np.ndarray] = {}
        for name, values in obj.items():
            if not isinstance(name, str):
                raise PinoError(f"{what}: column names must be strings, got {name!r}")
            a = np.asarray(values)
            if a.ndim == 0:
                a = a.reshape(1)
            if a.ndim != 1:
                raise PinoError(f"{what}.{name}: a 1-D array (one value per design) expected, got shape {a.shape}")
            if a.dtype.kind not in "fiu":
                raise PinoError(f"{what}.{name}: numbers expected, got {a.dtype}")
            cols[name] = a
        lengths = {name: len(a) for name, a in cols.items()}
        if len(set(lengths.values())) > 1:
            shown = ", ".join(f"{n}: {k}" for n, k in lengths.items())
            raise PinoError(f"{what}: columns of different lengths ({shown}); one value per design in each")
        return pl.DataFrame(cols)
    raise PinoError(
        f"{what}: expected a polars or pandas DataFrame, a pyarrow Table or a dict of arrays, got {type(obj).__name__}"
    )


def _frame(table: Any) -> pl.DataFrame:
    """A native result (an Arrow stream) as a polars DataFrame, without a copy."""
    return pl.DataFrame(table)


def _excitation(e: Any) -> Any:
    """The ``excitation`` argument as the native module reads it (a path as ``str``, a mapping
    as ``dict``, a NumPy integer as ``int``); the native module checks it."""
    if isinstance(e, os.PathLike):
        return os.fspath(e)
    if isinstance(e, Mapping):
        return dict(e)
    if isinstance(e, np.integer):
        return int(e)
    return e


def _warn_outside(df: pl.DataFrame) -> None:
    flagged = df.filter(pl.col("outside_training_range").is_not_null())
    if flagged.height:
        warnings.warn(
            f"{flagged.height} of {df.height} design row(s) outside the model's training ranges, where its "
            "predictions are extrapolations (column `outside_training_range`; strict=True refuses them)",
            stacklevel=3,
        )


class System:
    """A system description (``docs/systems.md``), compiled and checked as every stage does."""

    def __init__(self, native: Any) -> None:
        self._native = native

    @classmethod
    def load(cls, path: PathLike, values: Mapping[str, float | Sequence[float]] | None = None) -> System:
        """Reads the description at ``path`` (YAML); ``values`` overrides parameters in their
        declared units (a number; ``[lo, hi]`` for a sampled parameter's range). A problem in
        the file raises ``PinoError`` with one ``file:line`` line per problem, as the CLI."""
        return cls(_native.System.load(os.fspath(path), dict(values) if values else None))

    @property
    def name(self) -> str:
        """The system's name."""
        return self._native.name

    @property
    def path(self) -> str:
        """The description's file."""
        return self._native.path

    @property
    def hash(self) -> str:
        """Content hash of the description and its overrides."""
        return self._native.hash

    @property
    def design_parameters(self) -> list[str]:
        """The sampled parameters (the columns of a design), in value order."""
        return self._native.design_parameters

    @property
    def indices_from(self) -> float:
        """The time (s) from which every index reads a record (the description's
        ``indices_from``, docs/systems.md): the points before it are the simulation's start-up."""
        return self._native.indices_from

    @property
    def parameters(self) -> pl.DataFrame:
        """Every parameter: name, unit (as declared), kind (sampled / fixed / derived),
        nominal (a sampled one's default, a fixed one's value), min and max (a sampled one's
        range), expr (a derived one's formula), doc."""
        return pl.DataFrame(self._native._parameters())

    @property
    def columns(self) -> pl.DataFrame:
        """The columns ``simulate`` returns (those of ``simulation.parquet``): name, unit,
        kind (id, time, solution, velocity, acceleration, excitation, force, other)."""
        return pl.DataFrame(self._native._columns())

    @property
    def indices(self) -> pl.DataFrame:
        """The engineering indices (``docs/indices.md``): name, unit, limit (the default pass
        limit, null without one), definition."""
        return pl.DataFrame(self._native._indices(), schema_overrides={"limit": pl.Float64})

    def simulate(
        self,
        designs: Any,
        *,
        duration: float,
        dt: float,
        output_every: int,
        excitation: Excitation = None,
        start: str = "equilibrium",
        x0: float = 0.0,
        startup_zero_fraction: float = 0.0,
        startup_ramp_fraction: float = 0.0,
        progress: bool = True,
        return_failures: bool = False,
    ) -> pl.DataFrame | tuple[pl.DataFrame, pl.DataFrame]:
        """Runs the exact solver (the ``simulate`` stage's engine) on every design, in
        parallel on all cores with the GIL released.

        ``designs``: one row per design, a column per design parameter (missing ones take
        their nominal values), optionally ``sample_id`` (the key of the design's rows in the
        result and the stream or sample of the excitation it runs on; default: its row
        number) and ``split`` (ignored). ``excitation`` (needed for a system with generated
        profiles): a seed (``int``), ``{"seed": N, "dx": m, "length": m}`` (generated as
        ``irregularity`` does; ``dx`` defaults to 0.1 m, ``length`` to the farthest point
        read over the description's sampling ranges in this run plus ``dx``, rounded up to
        whole 10 m and at least the longest generated wavelength: give ``length`` to keep
        one road across runs of other durations) or a profile table (``sample_id``, ``x``
        in m, ``eta`` in m, positive downward: the ``irregularity`` artifact, or its file's
        path). ``duration`` (s), ``dt`` (s, below the
        stability bound), ``output_every`` (steps per stored row), ``start``
        (``"equilibrium"`` or ``"rest"``), ``x0`` (m, the moving frame at t = 0), the two
        start-up fractions (of the duration) are the run controls of ``pipeline.yaml``.

        Returns the table of ``simulation.parquet`` for the same inputs (same columns, units
        and values, bit for bit; rows by ``sample_id``, then ``t`` in s). Designs whose state
        diverged are left out with a warning; ``return_failures=True`` also returns them
        (``sample_id``, ``reason``)."""
        sim, failed = self._native._simulate(
            _designs(designs),
            _excitation(excitation),
            float(duration),
            float(dt),
            int(output_every),
            start,
            float(x0),
            float(startup_zero_fraction),
            float(startup_ramp_fraction),
            bool(progress),
        )
        sim, failed = _frame(sim), _frame(failed)
        if failed.height:
            warnings.warn(f"{failed.height} design(s) diverged: {failed.rows()[:5]}", stacklevel=2)
        return (sim, failed) if return_failures else sim

    def __repr__(self) -> str:
        return repr(self._native)


class _Answers:
    """What a ``Model`` and a ``Surrogate`` answer alike: predictions and indices of designs."""

    def __init__(self, native: Any) -> None:
        self._native = native

    @property
    def system_name(self) -> str:
        """The name of the system description it was trained on."""
        return self._native.system_name

    @property
    def design_parameters(self) -> list[str]:
        """The design parameters it reads, in value order."""
        return self._native.design_parameters

    def predict(
        self,
        designs: Any,
        *,
        excitation: Excitation = None,
        excitation_id: int | None = None,
        x0: float | None = None,
        coverage: float | None = None,
        batch: int = 16,
        strict: bool = False,
    ) -> pl.DataFrame:
        """Time histories of every design (the table of ``predict --out``): ``set`` (the
        design's row), ``t`` (s), the predicted outputs (displacements in m or rad, forces in N),
        the rigid DOFs' velocities and accelerations, the excitations (m), with a calibration
        a band ``<channel>_lo``/``_hi`` at ``coverage`` (default 0.9), and
        ``outside_training_range`` (``name=value`` of each parameter outside the training
        ranges, null inside; a warning, or ``PinoError`` with ``strict=True``). A surrogate
        answers each channel and its band from the member routed to it.

        ``excitation``: a seed (``int``: the profiles generated as ``irregularity`` does with
        the training dataset's ``dx`` and ``length``), ``{"seed": N, "dx": m, "length": m}``
        (``dx`` and ``length`` default to the dataset's) or a profile table (``sample_id``,
        ``x``, ``eta`` in m; a DataFrame or a Parquet file's path). Each row runs on the
        stream (generated) or sample (table) of its ``sample_id`` when ``designs`` has that
        column (the answer of ``predict --profile-id SAMPLE_ID``, row by row), else every row
        on ``excitation_id`` (default: stream 0, or the table's first sample). ``x0`` (m)
        overrides the run's start."""
        df = _frame(
            self._native._answer("histories", _designs(designs), _excitation(excitation), _id(excitation_id), x0, coverage, int(batch), bool(strict))
        )
        _warn_outside(df)
        return df

    def indices(
        self,
        designs: Any,
        *,
        excitation: Excitation = None,
        excitation_id: int | None = None,
        x0: float | None = None,
        coverage: float | None = None,
        batch: int = 16,
        strict: bool = False,
    ) -> pl.DataFrame:
        """The engineering indices of every design, one row each (the table of ``predict
        --indices``): ``set``, the design parameters, each index in its unit, ``window_s``
        (s), ``pass`` (Boolean), ``failed`` (the limits exceeded; null when none),
        ``outside_training_range`` (null inside); with a calibration also ``coverage``,
        ``extrapolated`` (Boolean), ``<index>_lo``/``_hi`` and the three-valued verdicts
        ``<index>_verdict``, ``verdict`` (pass / uncertain / fail). The numbers are those of
        ``predict`` for the same designs and excitation, bit for bit (a surrogate: each index,
        its interval and verdict those of the member routed to it; ``pass``, ``failed`` and
        ``verdict`` judged on the assembled indices). Arguments as ``predict``."""
        df = _frame(
            self._native._answer("indices", _designs(designs), _excitation(excitation), _id(excitation_id), x0, coverage, int(batch), bool(strict))
        )
        _warn_outside(df)
        return df

    def __repr__(self) -> str:
        return repr(self._native)


class Model(_Answers):
    """A trained model (a ``train`` output) with its calibration when given."""

    @classmethod
    def load(cls, dir: PathLike, calibration: PathLike | None = None) -> Model:
        """Loads ``model.safetensors`` and ``model.json`` from ``dir``; ``calibration``: the
        ``calibrate`` stage's output directory (the model's own file is found in it) or a
        ``calibration.json``. A calibration of another model is refused (``PinoError``)."""
        return cls(_native.Model.load(os.fspath(dir), None if calibration is None else os.fspath(calibration)))

    @property
    def dir(self) -> str:
        """The model's directory."""
        return os.fspath(self._native.dir)

    @property
    def algorithm(self) -> int:
        """The training algorithm (1-5, docs/learning.md)."""
        return self._native.algorithm

    @property
    def calibrated(self) -> bool:
        """Whether a calibration was loaded."""
        return self._native.calibration is not None

    def export_onnx(self, path: PathLike, spectral: str | None = None, levels: list[float] | None = None) -> str:
        """Writes the model, its calibrated intervals and its training-range flag as one ONNX
        file (docs/export.md), atomically; ``spectral``: ``"matmul"`` (opset 13, default) or
        ``"dft"`` (opset 17); ``levels``: the interval levels (default: those the calibration
        supports). Returns what was written. A refusal raises ``PinoError``."""
        return self._native._export_onnx(os.fspath(path), spectral, levels)


class Surrogate(_Answers):
    """The ``surrogate`` stage's output: several trained models, each index and channel
    answered by the one most accurate on it over the validation split, with its calibrated
    interval or band (docs/uncertainty.md); ``predict`` and ``indices`` as ``Model``'s."""

    @classmethod
    def load(cls, dir: PathLike) -> Surrogate:
        """Loads the surrogate in ``dir`` (``surrogate.json`` and ``members/``: ``pipeline
        show surrogate``). A member whose files changed since the surrogate was built, or a
        manifest of another system, raises ``PinoError`` naming the file and the member model,
        as ``predict --surrogate`` does."""
        return cls(_native.Surrogate.load(os.fspath(dir)))

    @property
    def dir(self) -> str:
        """The surrogate's directory."""
        return os.fspath(self._native.dir)

    @property
    def members(self) -> list[str]:
        """The member models' names (``algorithm-5``, ``algorithm-5-rates``, ...)."""
        return self._native.members

    @property
    def index_routes(self) -> dict[str, str]:
        """Each index (the description's order) and the member answering it."""
        return dict(self._native.index_routes)

    @property
    def channel_routes(self) -> dict[str, str]:
        """Each predicted channel (column order) and the member answering it."""
        return dict(self._native.channel_routes)

    @property
    def calibrated(self) -> bool:
        """Whether every member answering a quantity has calibrated intervals."""
        return self._native.has_intervals


def _id(i: Any) -> int | None:
    if i is None:
        return None
    if isinstance(i, bool) or not isinstance(i, (int, np.integer)):
        raise PinoError(f"excitation_id = {i!r}: allowed an integer >= 0")
    return int(i)


def _sets(values: Mapping[str, Any] | None) -> list[str]:
    """``{"stage.key": value}`` as the CLI's ``--set stage.key=value`` (values as YAML)."""
    return [f"{k}={json.dumps(v)}" for k, v in (values or {}).items()]


class Pipeline:
    """A pipeline file (``pipeline.yaml``, ``configs/*.yaml``) in its workspace, driven as the
    ``pipeline`` command drives it."""

    def __init__(
        self,
        path: PathLike = "pipeline.yaml",
        *,
        workspace: PathLike | None = None,
        bin_dir: PathLike | None = None,
        set: Mapping[str, Any] | None = None,
    ) -> None:
        """``path``: the pipeline file, relative to ``workspace`` when one is given, else to
        the current directory; ``workspace``: where ``artifacts/`` lives (default: the file's
        ``workspace:`` key, relative to the file, else the file's directory: as the
        ``pipeline`` command, a file opened from anywhere runs in its own workspace);
        ``bin_dir``: where the stage binaries are (default: the file's ``bin_dir``, or
        ``PINO_BIN_DIR``); ``set``: ``{"stage.key": value}`` overrides applied to every call
        (``--set``)."""
        self._native = _native.Pipeline(
            os.fspath(path),
            None if workspace is None else os.fspath(workspace),
            None if bin_dir is None else os.fspath(bin_dir),
            _sets(set),
        )

    @property
    def workspace(self) -> str:
        """The workspace the pipeline runs in (absolute when derived from the file)."""
        return os.fspath(self._native.workspace)

    def status(self) -> pl.DataFrame:
        """Every unit: ``unit``, ``state`` (fresh, stale, never run, running, submitted) and
        ``detail`` (why stale, progress), as ``pipeline status``."""
        return pl.DataFrame(self._native._status())

    def run(
        self,
        targets: Sequence[str] | str | None = None,
        *,
        set: Mapping[str, Any] | None = None,
        force: bool = False,
        jobs: int = 1,
    ) -> None:
        """Runs ``targets`` (stages or expansions such as ``"train[algorithm=5]"``; default
        every stage) and whatever upstream is stale, as ``pipeline run``; ``set`` adds
        overrides for this call. A failed stage raises ``PinoError``."""
        if isinstance(targets, str):
            targets = [targets]
        self._native._run(list(targets or []), _sets(set), bool(force), int(jobs))

    def show(self, stage: str, *, set: Mapping[str, Any] | None = None) -> list[str]:
        """The paths of ``stage``'s current output files, as ``pipeline show``."""
        return self._native._show(stage, _sets(set))

    def dir(self, stage: str, file: str, *, set: Mapping[str, Any] | None = None) -> str:
        """The directory holding ``file`` among ``stage``'s outputs (the first shard's)."""
        for p in self.show(stage, set=set):
            if os.path.basename(p) == file:
                return os.path.dirname(p)
        raise PinoError(f"{stage}: no output file {file}")


def study(
    models: Sequence[PathLike] | PathLike,
    study: Mapping[str, Any],
    *,
    out: PathLike,
    calibration: PathLike | None = None,
    **params: Any,
) -> dict[str, Any]:
    """Runs one design study (``docs/studies.md``) as the ``study`` stage does, with the same
    results: ``models`` (the ``surrogate`` stage's output directory, or ``train`` output
    directories, of which the one of ``params["algorithm"]``, default 5, answers alone),
    ``study`` (the declaration: ``name``, ``kind`` = monte_carlo / sensitivity / optimise /
    critical_speed, ...), ``calibration`` (with models: the ``calibrate`` output), and the
    stage's other parameters (``coverage``, ``seed``, ``batch_size``, ``bootstrap``,
    ``confidence``). Writes its files into ``out`` and returns
    ``{"summary": str, "files": [paths]}``."""
    surrogate = None
    if isinstance(models, (str, os.PathLike)):
        if os.path.isfile(os.path.join(os.fspath(models), "surrogate.json")):
            surrogate, models = os.fspath(models), []
        else:
            models = [models]
    summary = _native._study(
        [os.fspath(m) for m in models],
        json.dumps({"study": dict(study), **params}),
        os.fspath(out),
        None if calibration is None else os.fspath(calibration),
        surrogate,
    )
    files = sorted(os.path.join(r, f) for r, _, fs in os.walk(os.fspath(out)) for f in fs)
    return {"summary": summary, "files": files}
