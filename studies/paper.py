"""Reproduce the paper's Figs. 2 and 3 into reports/paper (same as `cdpr-sym study paper`)."""

from pathlib import Path

from cdpr_sym.studies.paper import run_paper_study

if __name__ == "__main__":
    out = Path(__file__).resolve().parents[1] / "reports" / "paper"
    for claim in run_paper_study(out):
        print(f"{claim.verdict:<13} {claim.claim}")
