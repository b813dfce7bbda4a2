"""Every command that writes refuses, before any work, a place it cannot write: one line
naming --out, exit status 2, nothing left behind."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from cdpr_sym.cli import main
from cdpr_sym.sweep import SweepConfig, run_sweep


def _commands(out: Path) -> dict[str, list[str]]:
    return {
        "sweep csv": ["sweep", "--robot", "aras3", "--pairs", "3", "--out", str(out / "x.csv")],
        "sweep parquet": ["sweep", "--robot", "aras3", "--pairs", "3", "--format", "parquet",
                          "--out", str(out / "x")],
        "certify workspace": ["certify", "workspace", "--robot", "aras3", "--out",
                              str(out / "x")],
        "certify pairs": ["certify", "pairs", "--robot", "aras3", "--controller", "smooth",
                          "--out", str(out / "x")],
        "calibrate plan": ["calibrate", "--plan", "--robot", "ipanema8", "--poses", "60",
                           "--kind", "self", "--out", str(out / "x.csv")],
        "study": ["study", "compare", "--pairs", "2", "--out", str(out / "x")],
        "workspace": ["workspace", "--robot", "aras3", "--out", str(out / "x")],
    }


@pytest.mark.parametrize("where", ["a file as folder", "proc"])
@pytest.mark.parametrize("name", list(_commands(Path("x"))))
def test_an_unwritable_out_is_refused_before_any_work(name, where, tmp_path, capsys):
    if where == "proc":
        if not Path("/proc/self").exists():
            pytest.skip("needs /proc")
        parent = Path("/proc")
    else:
        parent = tmp_path / "afile"
        parent.write_text("")
    started = time.perf_counter()
    status = main(_commands(parent)[name])
    err = capsys.readouterr().err.strip()
    assert status == 2, err
    assert len(err.splitlines()) == 1 and "out:" in err, err
    assert time.perf_counter() - started < 10  # refused before the work, not after it
    if where != "proc":
        assert [path.name for path in tmp_path.iterdir()] == ["afile"]


def test_the_sweep_api_refuses_an_unwritable_out_naming_it(tmp_path):
    from cdpr_sym import InvalidCase

    (tmp_path / "afile").write_text("")
    config = SweepConfig(robot="aras3", controllers=("pd-sat",), pairs=2, duration=0.5)
    with pytest.raises(InvalidCase) as refused:
        run_sweep(config, tmp_path / "afile" / "x.csv", workers=1, progress=False)
    assert refused.value.field == "out"
