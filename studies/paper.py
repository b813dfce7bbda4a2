"""Reproduce the paper's Figs. 2 and 3 into reports/paper (same as `cdpr-sym study paper`)."""

from pathlib import Path

from cdpr_sym.robot import preset
from cdpr_sym.studies.interface import StudyRequest
from cdpr_sym.studies.paper import STUDY

if __name__ == "__main__":
    out = Path(__file__).resolve().parents[1] / "reports" / "paper"
    request = StudyRequest(robot=preset("aras3"), source="aras3", progress=False)
    for claim in STUDY.run(out, request):
        print(f"{claim.verdict:<13} {claim.claim}")
