#!/usr/bin/python3
"""Stops `viscera run` of the 80 s palpation at random points and checks what it left behind.

For each signal (KILL, INT, TERM) and each trial, the run is stopped after a random delay; then
every file in --out must be complete and readable (each .vtu and .exo read by VTK's own reader), the .pvd
must list exactly the frames on disk, the wrench table (or, after kill -9, its streamed .partial)
must hold whole rows only, and after INT and TERM the summary must say "interrupted" and the exit
code be 130 or 143. Prints one line per trial and a table at the end; exits 1 if any check failed.

    /usr/bin/python3 scripts/kill-trials.py [--viscera build/apps/viscera/viscera] [--trials 10]
                                            [--scene scenes/gel_phantom.xml] [--seed 1]

Uses Debian's python3-vtk9 (hence /usr/bin/python3).
"""
import argparse
import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET

import vtk


def readable_vtu(path):
    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(path)
    errors = vtk.vtkFileOutputWindow()  # keep VTK's messages off the terminal
    errors.SetFileName(os.devnull)
    vtk.vtkOutputWindow.SetInstance(errors)
    reader.Update()
    grid = reader.GetOutput()
    return reader.GetErrorCode() == 0 and grid is not None and grid.GetNumberOfPoints() > 0


def exo_frames(path):
    """The number of frames VTK's reader finds in an Exodus series (0: unreadable or empty)."""
    reader = vtk.vtkExodusIIReader()
    reader.SetFileName(path)
    reader.UpdateInformation()
    reader.Update()
    blocks = reader.GetOutput()
    ok = blocks is not None and blocks.GetNumberOfPoints() > 0
    return reader.GetNumberOfTimeSteps() if ok else 0


def check(out, wrench, summary, sig, rc):
    problems = []
    if sig != "KILL" and rc == -getattr(signal, "SIG" + sig):
        # Stopped by the signal's default action before the run installed its handler (while the
        # program was loading): nothing may have been written.
        written = [f for f in (os.listdir(out) if os.path.isdir(out) else [])]
        if written or os.path.exists(summary) or os.path.exists(wrench):
            problems.append("stopped while loading, yet wrote " + (", ".join(written) or "outputs"))
        return problems, 0, 0, []
    files = sorted(os.listdir(out))
    temporaries = [f for f in files if ".tmp." in f]
    pvds = [f for f in files if f.endswith(".pvd")]
    vtus = {f for f in files if f.endswith(".vtu")}
    listed = set()
    for pvd in pvds:
        try:
            root = ET.parse(os.path.join(out, pvd)).getroot()
        except ET.ParseError as e:
            problems.append(f"{pvd} does not parse: {e}")
            continue
        listed |= {d.get("file") for d in root.iter("DataSet")}
    if listed != vtus:
        problems.append(f".pvd lists {len(listed)} frames, {len(vtus)} on disk")
    unreadable = [f for f in sorted(vtus) if not readable_vtu(os.path.join(out, f))]
    if unreadable:
        problems.append(f"{len(unreadable)} unreadable frames, e.g. {unreadable[0]}")
    # An Exodus series takes its name when the run ends: after INT or TERM it is there and
    # whole; after KILL only its temporary is (and an earlier file, if there was one).
    exos = [f for f in files if f.endswith(".exo")]
    if sig != "KILL" and not exos and any(".exo.tmp." in f for f in files):
        problems.append("the Exodus series was not put in place")
    frames = len(vtus)
    for f in exos:
        n = exo_frames(os.path.join(out, f))
        if n == 0:
            problems.append(f"{f} is unreadable")
        frames += n
    table = wrench if os.path.exists(wrench) else wrench + ".partial"
    rows = 0
    if os.path.exists(table):
        with open(table) as f:
            lines = f.read().split("\n")
        if lines[-1] != "":
            problems.append(f"{os.path.basename(table)} ends inside a row")
        width = lines[0].count(",")
        bad = [l for l in lines[1:-1] if l.count(",") != width]
        if bad:
            problems.append(f"{len(bad)} rows of {os.path.basename(table)} are cut")
        rows = len(lines) - 2
    else:
        problems.append("no wrench table")
    if sig != "KILL":
        try:
            status = json.load(open(summary)).get("status")
        except (OSError, ValueError) as e:
            status = f"unreadable ({e})"
        if status != "interrupted":
            problems.append(f"summary status {status}")
        if rc != 128 + getattr(signal, "SIG" + sig):
            problems.append(f"exit code {rc}")
    return problems, frames, rows, temporaries


def default_signals():
    # A script started in the background has SIGINT ignored, and children inherit that.
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--viscera", default=os.path.join(here, "..", "build", "apps", "viscera", "viscera"))
    ap.add_argument("--scene", default=os.path.join(here, "..", "scenes", "gel_phantom.xml"))
    ap.add_argument("--trials", type=int, default=10)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--latest", type=float, default=30.0, help="latest stop, seconds after the start")
    ap.add_argument("--signals", default="KILL,INT,TERM", help="signals to try, comma-separated")
    a = ap.parse_args()
    rng = random.Random(a.seed)
    failures = 0
    table = []
    for sig in a.signals.split(","):
        for trial in range(a.trials):
            with tempfile.TemporaryDirectory() as tmp:
                out, wrench, summary = (os.path.join(tmp, n) for n in ("out", "w.csv", "s.json"))
                delay = rng.uniform(0.5, a.latest)
                p = subprocess.Popen([a.viscera, "run", a.scene, "--time", "80", "--quiet", "--out", out,
                                      "--wrench", wrench, "--summary", summary],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                     preexec_fn=default_signals)
                time.sleep(delay)
                p.send_signal(getattr(signal, "SIG" + sig))
                rc = p.wait()
                problems, frames, rows, temps = check(out, wrench, summary, sig, rc)
                failures += bool(problems)
                table.append((sig, delay, frames, rows, len(temps), problems))
                print(f"SIG{sig:<4} after {delay:5.1f} s: {frames:4d} frames, {rows:6d} wrench rows, "
                      f"{len(temps)} temporaries left: " + ("; ".join(problems) if problems else "ok"), flush=True)
    print(f"\n{len(table)} trials, {failures} with a problem")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
