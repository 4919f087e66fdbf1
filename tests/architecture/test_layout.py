"""The installed layout: featherstar.* importable, none of the generic top-level names."""
from __future__ import annotations

import subprocess
import sys

PROBE = """
import importlib.util, json
names = ["featherstar", "featherstar.cosim", "featherstar.cosim.swimmer", "featherstar.hil", "featherstar.optimizer",
         "featherstar.fmu_src", "featherstar.dashboard", "cosim", "hil", "optimizer", "fmu_src", "dashboard"]
print(json.dumps({n: importlib.util.find_spec(n) is not None for n in names}))
"""


def test_featherstar_packages_install_and_no_generic_top_level_name_does(tmp_path):
    """From outside the checkout (as a user's script runs), the installed names are featherstar.*."""
    out = subprocess.run([sys.executable, "-c", PROBE], cwd=tmp_path, capture_output=True, text=True, check=True)
    found = __import__("json").loads(out.stdout)
    assert all(found[n] for n in found if n.startswith("featherstar")), found
    assert not any(found[n] for n in ("cosim", "hil", "optimizer", "fmu_src", "dashboard")), found
