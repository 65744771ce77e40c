"""Sweeps the curtain's stretch stiffness from Python and plots how far its bottom edge sags.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/curtain_sag.py [out.png]

Each stiffness is a Sandbox of the `curtain` demo with the wind switched off, stepped 2 s (120 frames) until
it hangs still; the sag is how far the bottom row's middle sits below where it started (the cloth's own
length when it neither stretched nor fell)."""

import sys

import matplotlib

matplotlib.use("Agg")  # no display: write a file
import matplotlib.pyplot as plt
import numpy as np

import tumble

stiffness = np.geomspace(200.0, 20000.0, 9)
sag = []
for k in stiffness:
    sim = tumble.Sandbox("curtain", set=[f"curtain.cloth.stretch={k}", "wind.force_field.strength=[0.0, 0.0, 0.0]"], threads=1)
    rows, cols = 35, 35
    start = sim.x("curtain")[(rows - 1) * cols + cols // 2][1]
    sim.step(120)
    now = sim.x("curtain")[(rows - 1) * cols + cols // 2][1]
    sag.append(start - now)
    print(f"stretch {k:8.0f} N/m: bottom sags {start - now:.4f} m")

plt.semilogx(stiffness, sag, "o-")
plt.xlabel("stretch stiffness (N/m)")
plt.ylabel("sag of the bottom edge after 2 s (m)")
plt.title("curtain: sag against stiffness (tumble.Sandbox)")
plt.grid(True, which="both", alpha=0.3)
out = sys.argv[1] if len(sys.argv) > 1 else "curtain_sag.png"
plt.savefig(out, dpi=100)
print("wrote", out)
