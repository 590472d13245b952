"""Run by pvpython (tests/archive/interop_test.py): opens an XDMF sidecar with ParaView's
default reader and prints what it sees as JSON on the last line of stdout."""
import json
import sys

from paraview import servermanager as sm
from paraview.simple import OpenDataFile, UpdatePipeline

path, frame, node = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
r = OpenDataFile(path)
times = list(r.TimestepValues)
UpdatePipeline(time=times[frame], proxy=r)
d = sm.Fetch(r)
if d.IsA("vtkMultiBlockDataSet"):
    d = d.GetBlock(0)
pd, cd = d.GetPointData(), d.GetCellData()
u = pd.GetArray("displacement")
a = cd.GetArray("activation")
g = cd.GetArray("region")
print(json.dumps({
    "reader": r.GetXMLName(),
    "times": times,
    "points": d.GetNumberOfPoints(),
    "cells": d.GetNumberOfCells(),
    "cell_type": d.GetCellType(0),
    "position": list(d.GetPoint(node)),
    "displacement": list(u.GetTuple3(node)) if u else None,
    "activation_range": list(a.GetRange()) if a else None,
    "region_range": list(g.GetRange()) if g else None,
}))
