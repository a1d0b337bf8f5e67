"""Data for the command-line benchmark of a formula model (BENCHMARKS.md): thesis Example 5.1,
z = sin(A)x + B^2 y cos(x) + sqrt(C)x^2 + D y^2 + E x/y + F 2x/y, A..F = 1..6, 200 000 samples,
x, y uniform on [0.5, 2], noise 0.01.   python3 bench/ex51_csv.py > ex51.csv   (needs numpy)
"""
import sys

import numpy as np

rng = np.random.default_rng(1)
n = 200_000
x = rng.uniform(0.5, 2, n)
y = rng.uniform(0.5, 2, n)
A, B, C, D, E, F = 1, 2, 3, 4, 5, 6
z = (np.sin(A) * x + B**2 * y * np.cos(x) + np.sqrt(C) * x**2 + D * y**2 + E * x / y
     + F * 2 * x / y + 0.01 * rng.normal(size=n))
np.savetxt(sys.stdout, np.column_stack([x, y, z]), delimiter=",", header="x,y,z", comments="")
