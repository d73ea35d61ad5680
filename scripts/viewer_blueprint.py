"""Writes a Rerun blueprint (.rbl) for peridyn recordings: the damage field and the scheme mask
(hybrid runs: standard / WLS), energies, the Ω_s fraction and the applied commands beside them,
the time line following the latest frame.

    python3 scripts/viewer_blueprint.py OUT.rbl
"""

import sys

import rerun.blueprint as rrb

blueprint = rrb.Blueprint(
    rrb.Horizontal(
        rrb.Spatial2DView(origin="/nodes/damage", name="damage"),
        rrb.Spatial2DView(origin="/nodes/scheme", name="scheme: standard (orange) / WLS (blue)"),
        rrb.Vertical(
            rrb.TimeSeriesView(origin="/metrics/energy", name="energies"),
            rrb.TimeSeriesView(origin="/metrics/hybrid/omega_s_fraction", name="Ω_s fraction"),
            rrb.TextLogView(origin="/control/commands", name="commands applied"),
        ),
        column_shares=[2, 2, 2],
    ),
    rrb.TimePanel(timeline="step", play_state="following"),
    collapse_panels=True,
)
blueprint.save("peridyn", sys.argv[1])
