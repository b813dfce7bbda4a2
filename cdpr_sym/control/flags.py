"""The bits of a control step's ``flags``: which fallback or limit acted in that step.

Every controller reports them per step; trajectories, sweeps and the exported C header read
them from here.
"""

from __future__ import annotations

#: Remark 2: ||dq|| below the low-speed threshold, A ~ 0, the law is saturated instead.
FLAG_LOW_SPEED = 1
#: beta <= 0 in (20): Assumption 1 in its ball form fails here; the law is saturated.
FLAG_BETA = 2
#: The commanded tension was clipped to [T_min, T_max].
FLAG_SATURATED = 4
#: alpha < 1: the PD action was scaled down to keep the tension in the box.
FLAG_ALPHA = 8
#: |det W| fell below the singularity threshold. The simulation stops before applying this
#: command, so a Trajectory ends at the previous step and records ``stop_reason`` instead.
FLAG_SINGULAR = 16
#: The exact tension box is unreachable for every alpha in (0, 1] (box and l∞ designs), or a
#: planner found no admissible plan.
FLAG_INFEASIBLE = 32

FLAG_NAMES = {FLAG_LOW_SPEED: "low_speed", FLAG_BETA: "beta_nonpositive",
              FLAG_SATURATED: "saturated", FLAG_ALPHA: "alpha_below_one",
              FLAG_SINGULAR: "singular", FLAG_INFEASIBLE: "infeasible"}

#: Only these flags mean "the designed law did not apply as stated"; alpha < 1 is the design.
FALLBACK_FLAGS = FLAG_LOW_SPEED | FLAG_BETA | FLAG_INFEASIBLE
