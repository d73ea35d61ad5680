#!/usr/bin/env python3
"""Remake a field plot from a peridyn recording alone (independent reader: rerun-sdk).

    pip install 'rerun-sdk[datafusion]==0.36.*' matplotlib
    python3 scripts/plot_field.py RECORDING.rrd OUT.png [--field damage] [--step N]

Plots the raw per-node values stored beside the points of `/nodes/<field>` at the last (or the
given) logged step, at the logged positions.
"""
import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import rerun as rr  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("recording")
    parser.add_argument("out")
    parser.add_argument("--field", default="damage")
    parser.add_argument("--step", type=int, default=None)
    args = parser.parse_args()

    entity = f"/nodes/{args.field}"
    frames = (
        rr.experimental.RrdReader(args.recording)
        .stream()
        .collect()
        .reader(index="step", contents=entity)
        .to_pandas()
    )
    frames = frames.dropna(subset=[f"{entity}:{args.field}"])
    row = frames.iloc[-1] if args.step is None else frames[frames["step"] == args.step].iloc[0]
    kind = "Points3D" if f"{entity}:Points3D:positions" in frames.columns else "Points2D"
    positions = np.array(row[f"{entity}:{kind}:positions"].tolist())
    values = np.array(row[f"{entity}:{args.field}"].tolist()).ravel()

    fig, ax = plt.subplots(figsize=(5, 8))
    scatter = ax.scatter(
        positions[:, 0] * 1e3, positions[:, 1] * 1e3, c=values, s=0.3, cmap="viridis"
    )
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_title(f"{args.field} at step {int(row['step'])}")
    fig.colorbar(scatter, label=args.field)
    fig.savefig(args.out, dpi=110, bbox_inches="tight")


if __name__ == "__main__":
    main()
