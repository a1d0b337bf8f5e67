"""Reference for physid-sim's closed-cylinder compression (issue 7, verification 2): adiabatic
compression of air from 1 bar, 300 K at BDC to TDC and back, valves shut, in this engine's
geometry (bore 54 mm, crank radius 25.7 mm, rod 88 mm, compression ratio 9.5) at 1000 rpm,
computed by Cantera: an IdealGasReactor (air.yaml, O2:N2 = 1:79/21 as physid's air) whose
wall moves with the piston, s(θ) = r + L − r·cos θ − sqrt(L² − r² sin² θ).

Run: python3 gen_cantera_compression.py  (cantera 3.2) -> cantera_compression.json
"""
import json
import math

import cantera as ct

b, r, L, kappa = 0.054, 0.0257, 0.088, 9.5
rpm = 1000.0
w = rpm * math.pi / 30.0
ap = math.pi * b * b / 4.0
vd = ap * 2.0 * r
vc = vd / (kappa - 1.0)


def s(th):
    return r + L - r * math.cos(th) - math.sqrt(L * L - (r * math.sin(th)) ** 2)


def ds(th):
    return r * math.sin(th) + r * r * math.sin(th) * math.cos(th) / math.sqrt(L * L - (r * math.sin(th)) ** 2)


gas = ct.Solution("air.yaml")
gas.TPX = 300.0, 1.0e5, "O2:1, N2:3.761904761904762"
th0 = math.pi  # BDC
reactor = ct.IdealGasReactor(gas, energy="on", clone=False)
reactor.volume = vc + ap * s(th0)
env = ct.Reservoir(ct.Solution("air.yaml"), clone=False)
wall = ct.Wall(env, reactor, A=ap)
# Positive wall velocity moves it toward the reactor (right), dV/dt = −A·v; the piston gives
# dV/dt = A·s'(θ)·ω, so v = −s'(θ)·ω.
wall.velocity = ct.Func1(lambda t: -ds(th0 + w * t) * w)
net = ct.ReactorNet([reactor])
net.rtol, net.atol = 1e-12, 1e-16
t_tdc = math.pi / w
p_max, t_max, th_pmax = 0.0, 0.0, 0.0
n = 20000
for k in range(1, 2 * n + 1):
    t = 2 * t_tdc * k / (2 * n)
    net.advance(t)
    if reactor.phase.P > p_max:
        p_max, t_max, th_pmax = reactor.phase.P, reactor.T, math.degrees(th0 + w * t)
out = {"cantera": ct.__version__, "p0_pa": 1.0e5, "t0_k": 300.0, "rpm": rpm,
       "p_max_pa": p_max, "t_max_k": t_max, "theta_p_max_deg": th_pmax,
       "p_end_pa": reactor.phase.P, "t_end_k": reactor.T}
print(out)
json.dump(out, open("cantera_compression.json", "w"), indent=1)
