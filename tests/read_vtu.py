#!/usr/bin/env python3
"""Reads a .pvd time series and its .vtu files with meshio (an independent VTK reader) and
prints, as JSON, per file: its time, point count, coordinates and point data."""
import json
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio

pvd = Path(sys.argv[1])
out = []
for ds in ET.parse(pvd).getroot().iter("DataSet"):
    mesh = meshio.read(pvd.parent / ds.attrib["file"])
    out.append(
        {
            "time": float(ds.attrib["timestep"]),
            "file_time": float(mesh.field_data["TimeValue"].ravel()[0]),
            "points": len(mesh.points),
            "cells": sum(len(c.data) for c in mesh.cells),
            "positions": mesh.points.ravel().tolist(),
            "point_data": {k: v.ravel().tolist() for k, v in mesh.point_data.items()},
            "run": bytes(mesh.field_data["run"].astype("uint8").ravel().tolist()).decode(),
        }
    )
json.dump(out, sys.stdout)
