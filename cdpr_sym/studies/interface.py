"""What every study is to the command line: its options, a compute step, a report step.

A study computes into a folder first (``compute``): per-run files, which the study
regenerates and git does not keep (``runs/*.npz``, sweep tables, ``runs.json``), and
``study.json``. The report step then works from files alone: with the per-run files at
hand it condenses them into small aggregate files (``aggregate``: ``summary.json`` and the
like, and the figures), and it always writes ``report.md`` from ``study.json`` and the
aggregate files (``render``). A clean checkout holds ``study.json``, the aggregates and
the figures, so ``cdpr-sym report NAME reports/NAME`` rebuilds the report's text there too.

This module imports nothing heavy: the command line reads it to build its parser.
"""

from __future__ import annotations

import abc
import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

from cdpr_sym.errors import CdprError, InvalidCase

if TYPE_CHECKING:
    from cdpr_sym.robot import Robot

#: The file naming a computed study (its kind, the robot and what it measured besides runs).
STUDY_FILE = "study.json"
#: The report every study writes into its folder.
REPORT_FILE = "report.md"
#: The digests of the per-run files a computed study wrote (small, kept in git): a report
#: redrawn from run files of another run (a checkout's older tables beside a newer
#: study.json) is refused instead of silently reporting their numbers.
RUNS_DIGEST_FILE = "runs.sha256.json"


@dataclasses.dataclass(frozen=True)
class StudyOptions:
    """What a study takes from the command line.

    Every study takes ``--pairs`` and ``--seed`` (checked the same way; a study that draws no
    pairs ignores them) and ``--out``.

    Attributes
    ----------
    robot : bool
        Whether ``--robot`` (a preset name or a robot TOML file) is accepted.
    default_robot : str or None
        The preset run without ``--robot``; None: the study runs :attr:`own_robots`.
    own_robots : tuple of str
        The presets the study runs itself (without ``--robot``, or always when
        :attr:`robot` is False).
    default_pairs : int
        Start/goal pairs per sweep without ``--pairs``.
    """

    robot: bool = True
    default_robot: str | None = "aras3"
    own_robots: tuple[str, ...] = ()
    default_pairs: int = 200


@dataclasses.dataclass(frozen=True)
class StudyRequest:
    """The checked options of one run of a study.

    Attributes
    ----------
    robot : Robot or None
        The robot to study, its case checked; None: the study's own robots.
    source : str or None
        How it was named (a preset name or a robot file, which a sweep's sidecar records to
        check a resume against), or None with :attr:`robot`.
    pairs : int
        Start/goal pairs of the study's sweeps.
    seed : int
        Seed of the pair draw (>= 0).
    progress : bool
        Whether to show progress while computing.
    """

    robot: Robot | None
    source: str | None
    pairs: int = 200
    seed: int = 0
    progress: bool = True


class Study(abc.ABC):
    """One study: its name and options, how it computes, and how it reports.

    Subclasses set :attr:`name` and :attr:`options` and write :meth:`compute`,
    :meth:`run_files`, :meth:`aggregate_files`, :meth:`aggregate`, :meth:`render` and
    :meth:`summary_lines`; :meth:`report` and :meth:`run` are the same for every study.

    The study object is the one way to run a study, for the command line and for code::

        study = study_by_name("compare")  # or the module's STUDY
        request = StudyRequest(robot=preset("aras3"), source="aras3", pairs=20, seed=1)
        study.compute(folder, request, designs=("l2", "box"))  # runs and study.json
        result = study.report(folder)  # aggregates, figures and report.md from the files
        result = study.run(folder, request, designs=("l2", "box"))  # the two in one

    ``compute(folder, request, *, ...)`` takes what every study takes in the
    :class:`StudyRequest` (robot, pairs, seed, progress), then what only this study takes
    as keyword-only options, each defaulting to what ``cdpr-sym study`` runs (the paper
    study's ``duration`` and ``long_duration`` in s, compare's and designs' ``designs``).
    """

    name: ClassVar[str]
    options: ClassVar[StudyOptions] = StudyOptions()
    #: Where the per-run files are (for the message when they are missing).
    runs_note: ClassVar[str] = "runs/ is not kept in git"
    #: Whether :meth:`run` records the per-run files' digests (:data:`RUNS_DIGEST_FILE`):
    #: the studies whose reports aggregate sweep tables (plain text, the same bytes from the
    #: same run), where a checkout's older tables were once reported beside a newer
    #: study.json. The others keep no record and are not checked.
    records_runs: ClassVar[bool] = False

    @abc.abstractmethod
    def compute(self, folder: Path, request: StudyRequest) -> None:
        """Simulate and write the per-run files and ``study.json`` into ``folder``.

        A study with options of its own takes them as keyword-only arguments after
        ``request``, each with the default ``cdpr-sym study`` runs."""

    @abc.abstractmethod
    def run_files(self, folder: Path) -> list[Path]:
        """The per-run files :meth:`aggregate` reads (``study.json`` may name them)."""

    @abc.abstractmethod
    def aggregate_files(self, folder: Path) -> list[Path]:
        """The small files :meth:`aggregate` writes and :meth:`render` reads."""

    @abc.abstractmethod
    def aggregate(self, folder: Path) -> None:
        """Condense the per-run files into the aggregate files, and draw the figures."""

    @abc.abstractmethod
    def render(self, folder: Path) -> Any:
        """Write ``report.md`` from ``study.json`` and the aggregate files alone; return
        the study's result (what ``--json`` prints and :meth:`summary_lines` reads)."""

    @abc.abstractmethod
    def summary_lines(self, result: Any) -> list[str]:
        """The short lines the command line prints for ``result``."""

    def check_request(self, request: StudyRequest) -> None:
        """Refuse, before any work, a request this study cannot run (its designs or
        plants on this robot); every request passes unless a study says otherwise."""
        return None

    def as_json(self, result: Any) -> Any:
        """``result`` as plain JSON values (it is one already, unless overridden)."""
        return result

    def has_runs(self, folder: Path) -> bool:
        """Whether every per-run file is in ``folder``."""
        return all(path.exists() for path in self.run_files(folder))

    def report(self, folder: Path) -> Any:
        """``report.md`` (and the aggregates and figures, when the per-run files are
        there) from the files in ``folder``; returns the study's result.

        Raises
        ------
        InvalidCase
            ``results``: neither the per-run files nor the aggregate files are there.
        """
        folder = Path(folder)
        try:
            if self.has_runs(folder):
                self.check_runs(folder)
                self.aggregate(folder)
            elif not all(path.exists() for path in self.aggregate_files(folder)):
                raise InvalidCase("results", f"{folder} has no stored runs "
                                  f"({self.runs_note}); run 'cdpr-sym study {self.name}' to "
                                  "compute them")
            return self.render(folder)
        except CdprError:
            raise  # already one line naming what is wrong
        except (LookupError, TypeError, AttributeError, ValueError, ArithmeticError
                ) as failure:
            # the stored files are input here: a field missing or of the wrong kind is a
            # damaged or foreign file, refused in one line naming the files read (a study
            # that checks its files names the very file and entry before this)
            raise InvalidCase("results", f"the stored files of {folder} "
                              f"({', '.join(self._read_files(folder))}) are not a computed "
                              f"{self.name} study's ({type(failure).__name__}: {failure}); "
                              f"run 'cdpr-sym study {self.name}' to compute them") from None
        except Exception as failure:
            from jinja2 import TemplateError

            if isinstance(failure, TemplateError):  # a value the template reads is missing
                raise InvalidCase("results", f"the stored files of {folder} "
                                  f"({', '.join(self._read_files(folder))}) lack what the "
                                  f"{self.name} report reads ({failure}); run 'cdpr-sym "
                                  f"study {self.name}' to compute them") from None
            raise

    def _read_files(self, folder: Path) -> list[str]:
        """The names of the stored files a report of ``folder`` reads."""
        return [STUDY_FILE, *(path.name for path in self.aggregate_files(folder))]

    def run(self, folder: Path, request: StudyRequest, **options: Any) -> Any:
        """Compute into ``folder`` (with the study's own keyword ``options``, see
        :meth:`compute`), record the per-run files' digests where the study keeps them
        (:attr:`records_runs`), then report from the files; returns the result."""
        self.compute(folder, request, **options)
        if self.records_runs:
            self.record_runs(folder)
        return self.report(folder)

    def record_runs(self, folder: Path) -> None:
        """Write :data:`RUNS_DIGEST_FILE`: the SHA-256 of each per-run file of ``folder``
        (a folder's files together), by its path relative to ``folder``."""
        from cdpr_sym.results.store import write_json

        folder = Path(folder)
        write_json(folder / RUNS_DIGEST_FILE, {
            "study": self.name,
            "runs": {path.relative_to(folder).as_posix(): _digest(path)
                     for path in self.run_files(folder) if path.exists()}})

    def check_runs(self, folder: Path) -> None:
        """Refuse (``results``), before reporting from them, per-run files that are not
        the ones this study computed: a recorded file whose digest differs, or a run file
        not recorded. A folder without :data:`RUNS_DIGEST_FILE` (computed before it was
        kept) is not checked."""
        from cdpr_sym.results.store import read_json

        record = Path(folder) / RUNS_DIGEST_FILE
        if not record.exists():
            return
        stored = read_json(record)
        digests = stored.get("runs") if isinstance(stored, dict) else None
        if not isinstance(digests, dict):
            raise InvalidCase("results", f"{record} is not a record of run files (expected "
                              "an object with 'runs': path -> SHA-256); run 'cdpr-sym study "
                              f"{self.name}' again, or remove it to report without the check")
        for path in self.run_files(folder):
            name = path.relative_to(folder).as_posix()
            if digests.get(name) != _digest(path):
                raise InvalidCase("results", f"{path} is not the file this {self.name} study "
                                  f"computed (its digest is not the one in "
                                  f"{RUNS_DIGEST_FILE}: a table of another run?); run "
                                  f"'cdpr-sym study {self.name}' again, or remove the run "
                                  "files to report from the stored aggregates")

    def check_folder(self, folder: Path) -> None:
        """Refuse, naming ``results``, a folder that holds no computed study of this kind.

        Raises
        ------
        InvalidCase
            No ``study.json``, a damaged one, or one of another study.
        """
        from cdpr_sym.results.store import read_json

        study = Path(folder) / STUDY_FILE
        if not study.exists():
            raise InvalidCase("results", f"{folder} holds no computed {self.name} study "
                              "(no study.json); run 'cdpr-sym study' first")
        data = read_json(study)
        kind = data.get("study") if isinstance(data, dict) else None
        if kind != self.name:
            held = f"a {kind} study" if isinstance(kind, str) else "no study's record"
            raise InvalidCase("results", f"{folder} holds {held}, not {self.name}")


def _digest(path: Path) -> str:
    """SHA-256 of a file, or of a folder's files (sorted by relative path, each path and
    content hashed), hex."""
    import hashlib

    digest = hashlib.sha256()
    files = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file())
    for file in files:
        digest.update(file.relative_to(path.parent).as_posix().encode())
        digest.update(b"\0")
        digest.update(file.read_bytes())
    return digest.hexdigest()
