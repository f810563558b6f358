"""Type stubs of the native module ``pino_mbd._pino_mbd`` (python/src). Call it through
``pino_mbd`` (python/pino_mbd/__init__.py), whose functions convert tables and give the
arguments their defaults; units are SI unless stated."""

from os import PathLike
from typing import Any, Literal, Optional

__version__: str

class PinoError(ValueError):
    """A refusal of pino-mbd: bad input named by file, line and field."""

class ArrowTable:
    """A result table exported through ``__arrow_c_stream__`` (one Arrow batch, no copy);
    each field carries its unit (``unit`` field metadata)."""

    @property
    def num_rows(self) -> int:
        """Number of rows."""
    @property
    def units(self) -> list[tuple[str, str]]:
        """``(column, unit)`` of every column."""
    def __arrow_c_stream__(self, requested_schema: Optional[object] = None) -> object:
        """The Arrow C stream capsule (PyCapsule protocol); ``requested_schema`` is ignored."""

class System:
    """A compiled system description."""

    @staticmethod
    def load(path: str | PathLike[str], values: Optional[dict[str, float | list[float]]] = None) -> System:
        """Reads and compiles the description at ``path``; ``values`` overrides parameters (a
        number in the parameter's unit, or ``[lo, hi]`` for a sampled one's range)."""
    @property
    def name(self) -> str:
        """The system's name."""
    @property
    def path(self) -> str:
        """The description's file."""
    @property
    def hash(self) -> str:
        """Content hash of the description and its overrides."""
    @property
    def indices_from(self) -> float:
        """The time (s) from which every index reads a record."""
    @property
    def design_parameters(self) -> list[str]:
        """The sampled parameters, in value order."""
    def _parameters(self) -> dict[str, list[Any]]:
        """Columns name, unit, kind, nominal, min, max, expr, doc of every parameter."""
    def _columns(self) -> dict[str, list[str]]:
        """Columns name, unit, kind of the simulation's columns."""
    def _indices(self) -> dict[str, list[Any]]:
        """Columns name, unit, limit (pass at or below; None without), definition."""
    def _simulate(
        self,
        designs: object,
        excitation: object,
        duration: float,
        dt: float,
        output_every: int,
        start: str,
        x0: float,
        startup_zero_fraction: float,
        startup_ramp_fraction: float,
        progress: bool,
    ) -> tuple[ArrowTable, ArrowTable]:
        """The solver on every design (an Arrow table), each on the excitation of its
        ``sample_id`` (a seed, ``{"seed", "dx", "length"}`` in m, a profile table or its
        path); ``duration`` and ``dt`` in s, ``x0`` in m, the fractions of the duration.
        Returns (simulation, failures)."""

class _Answers:
    """What a model and a surrogate answer alike."""

    @property
    def system_name(self) -> str:
        """The name of the system."""
    @property
    def design_parameters(self) -> list[str]:
        """The design parameters, in value order."""
    def _answer(
        self,
        table: Literal["histories", "indices"],
        designs: object,
        excitation: object,
        excitation_id: Optional[int],
        x0: Optional[float],
        coverage: Optional[float],
        batch: int,
        strict: bool,
    ) -> ArrowTable:
        """``histories``: time histories (``predict --out``), each row on the excitation of
        its ``sample_id``, else of ``excitation_id``; ``indices``: indices with intervals and
        verdicts (``predict --indices``), rows alike; ``x0`` in m."""

class Model(_Answers):
    """A trained model with its optional calibration."""

    @staticmethod
    def load(dir: str | PathLike[str], calibration: Optional[str | PathLike[str]] = None) -> Model:
        """Loads a ``train`` output and, when given, its calibration."""
    @property
    def dir(self) -> str:
        """The model's directory."""
    @property
    def calibration(self) -> Optional[str]:
        """The calibration given at load."""
    @property
    def algorithm(self) -> int:
        """The training algorithm (1-5)."""
    def _export_onnx(self, path: str, spectral: Optional[str], levels: Optional[list[float]]) -> str:
        """The model with its intervals as one ONNX file (``export``)."""

class Surrogate(_Answers):
    """The ``surrogate`` stage's output: each index and channel from its routed member."""

    @staticmethod
    def load(dir: str | PathLike[str]) -> Surrogate:
        """Loads ``surrogate.json`` and its members, verified against the manifest."""
    @property
    def dir(self) -> str:
        """The surrogate's directory."""
    @property
    def members(self) -> list[str]:
        """The member models' names."""
    @property
    def index_routes(self) -> list[tuple[str, str]]:
        """(index, member answering it), the description's order."""
    @property
    def channel_routes(self) -> list[tuple[str, str]]:
        """(channel, member answering it), column order."""
    @property
    def has_intervals(self) -> bool:
        """Whether every member answering a quantity has calibrated intervals."""

class Pipeline:
    """A pipeline file in its workspace."""

    def __init__(
        self,
        file: str,
        workspace: Optional[str],
        bin_dir: Optional[str],
        sets: list[str],
    ) -> None:
        """``file`` relative to ``workspace`` when given, else to the current directory;
        ``sets``: ``STAGE.KEY=VALUE`` overrides (YAML values) for every call."""
    @property
    def file(self) -> str:
        """The pipeline file."""
    @property
    def workspace(self) -> str:
        """The workspace: the one given, else the file's ``workspace:`` or directory."""
    def _status(self) -> dict[str, list[str]]:
        """Columns unit, state, detail."""
    def _run(self, targets: list[str], sets: list[str], force: bool, jobs: int) -> None:
        """``pipeline run``."""
    def _show(self, stage: str, sets: list[str]) -> list[str]:
        """``pipeline show``: the stage's current output files."""

def _study(
    models: list[str],
    params_json: str,
    out: str,
    calibration: Optional[str] = None,
    surrogate: Optional[str] = None,
) -> str:
    """One design study through the surrogate (or the models); ``params_json``: the ``study``
    stage's parameters. Returns its summary line."""
