"""The package's layers, checked: the oracle stands apart from the code it checks."""

from __future__ import annotations

import json
import subprocess
import sys

# The pipeline stages whose bugs the analytic reference exists to catch: it may import none of them.
STAGES = ("camera", "geometry", "intersect", "illumination", "shading", "shadows", "surface", "film", "render",
          "plan", "jit")


def test_the_oracle_imports_no_stage_of_the_renderer():
    probe = ("import json, sys; import raycast_phong.reference; "
             "print(json.dumps(sorted(m for m in sys.modules if m.startswith(('raycast_phong.', 'numba', 'embreex')))))")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    loaded = json.loads(done.stdout)
    assert "raycast_phong.reference" in loaded
    assert not [m for m in loaded if m.split(".")[-1] in STAGES or m.startswith(("numba", "embreex"))], loaded
