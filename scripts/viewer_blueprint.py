"""Writes a Rerun blueprint (.rbl) for peridyn recordings: the damage field large, energies and
the applied commands beside it, the time line following the latest frame.

    python3 scripts/viewer_blueprint.py OUT.rbl
"""

import sys

import rerun.blueprint as rrb

blueprint = rrb.Blueprint(
    rrb.Horizontal(
        rrb.Spatial2DView(origin="/nodes/damage", name="damage"),
        rrb.Vertical(
            rrb.TimeSeriesView(origin="/metrics/energy", name="energies"),
            rrb.TimeSeriesView(origin="/metrics/bonds", name="broken bonds"),
            rrb.TextLogView(origin="/control/commands", name="commands applied"),
        ),
        column_shares=[3, 2],
    ),
    rrb.TimePanel(timeline="step", play_state="following"),
    collapse_panels=True,
)
blueprint.save("peridyn", sys.argv[1])
