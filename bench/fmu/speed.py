"""How fast the cell runs as an FMU: FMPy's `simulate_fmu` of an exported scenario against
`physid simulate` of the same scenario, in one run of this script (a ratio, not last week's
number), and the FMU's C functions driven from a plain loop (FMPy's step API), so that FMPy's own
cost per communication point shows apart from the cell's.

    python bench/fmu/speed.py PHYSID_BIN [SECONDS]

Prints a JSON line per measurement (the section "The cell as an FMU (issue 46)" of
BENCHMARKS.md)."""
import json
import os
import subprocess
import sys
import tempfile
import time

import fmpy
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

BIN = sys.argv[1]
SECONDS = float(sys.argv[2]) if len(sys.argv) > 2 else 30.0


def wall(f):
    t0 = time.perf_counter()
    f()
    return time.perf_counter() - t0


with tempfile.TemporaryDirectory() as d:
    rec = os.path.join(d, "r.parquet")
    native = min(
        wall(lambda: subprocess.run(
            [BIN, "simulate", "--scenario", "shaft-steady", "--duration", str(SECONDS), "--recording", rec],
            check=True, capture_output=True))
        for _ in range(3)
    )
    print(json.dumps({"what": "physid simulate (parquet written)", "seconds": SECONDS, "wall_s": native,
                      "x_real_time": (SECONDS + 1) / native}))
    for v in (2, 3):
        fmu_path = os.path.join(d, f"cell{v}.fmu")
        subprocess.run([BIN, "fmu", "export", "--scenario", "shaft-steady", "--fmu", fmu_path, "--fmi", str(v)],
                       check=True, capture_output=True)
        for h in (1e-4, 1e-3):
            t = min(wall(lambda: fmpy.simulate_fmu(fmu_path, stop_time=SECONDS, output_interval=h))
                    for _ in range(2))
            print(json.dumps({"what": f"fmpy.simulate_fmu FMI {v}", "output_interval": h, "seconds": SECONDS,
                              "wall_s": t, "x_real_time": SECONDS / t, "vs_physid_simulate": t / native}))
    # The step API with one output read per step: FMPy's cost per call shows at small steps.
    md = read_model_description(os.path.join(d, "cell2.fmu"))
    unzip = extract(os.path.join(d, "cell2.fmu"))
    w = [x.valueReference for x in md.modelVariables if x.name == "omega_dy"]
    for h in (1e-4, 1e-3, 1e-2):
        fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier="physid_cell", instanceName="b")
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0, stopTime=SECONDS)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        n = round(SECONDS / h)

        def loop():
            for k in range(n):
                fmu.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
                fmu.getReal(w)

        t = wall(loop)
        fmu.terminate()
        fmu.freeInstance()
        print(json.dumps({"what": "FMI 2 step API, doStep + one getReal", "step": h, "seconds": SECONDS,
                          "wall_s": t, "x_real_time": SECONDS / t, "us_per_step": t / n * 1e6}))
