"""Large generated files (the NMPC solver, the interval code) are compiled at -O1 with the
exact-rounding flags: the same bits as -O2, in about half the compile time."""

from __future__ import annotations

import numpy as np
import pytest

from cdpr_sym import BuildOptions, simulate
from cdpr_sym.codegen.build import EXACT_FLAGS, lighter


def test_lighter_lowers_only_the_default_flags_optimisation_level():
    options = BuildOptions(timeout=60.0)
    light = lighter(options)
    assert light.flags == ("-O1", *EXACT_FLAGS[1:])
    assert light.timeout == 60.0 and light.backend == options.backend
    assert lighter(options, timeout=1200.0).timeout == 1200.0
    assert lighter(BuildOptions(timeout=2000.0), timeout=1200.0).timeout == 2000.0


def test_flags_the_user_chose_are_kept_as_given():
    chosen = BuildOptions(flags=("-O3", "-march=native"))
    assert lighter(chosen) is chosen


@pytest.mark.slow
def test_the_nmpc_solver_at_o1_gives_the_bits_of_o2(tmp_path, monkeypatch):
    """The loop builds its solver with ``lighter``; the same run with -O2 spelled out (flags
    the user chose, kept) must be the same bits: the exact flags forbid contraction,
    re-association and reciprocals at every level."""
    from cdpr_sym.closed_loop import sampled

    levels = []

    def recording(functions, name, *, options, **kwargs):
        levels.append(options.flags)
        return build(functions, name, options=options, **kwargs)

    build = sampled.build
    monkeypatch.setattr(sampled, "build", recording)
    runs = []
    for flags in (EXACT_FLAGS, (*EXACT_FLAGS, "-O2")):
        options = BuildOptions(cache_dir=tmp_path, flags=flags)
        runs.append(simulate("planar2", "nmpc", duration=0.5, build_options=options))
    assert levels == [lighter(BuildOptions()).flags, (*EXACT_FLAGS, "-O2")]
    light, full = runs
    for field in ("q", "dq", "tau", "memory"):
        np.testing.assert_array_equal(getattr(light, field), getattr(full, field))
    assert np.abs(np.diff(light.q, axis=0)).max() > 0  # the platform moved
