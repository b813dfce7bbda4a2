"""Certified verdicts: interval evaluation of CasADi functions and proofs over boxes."""
