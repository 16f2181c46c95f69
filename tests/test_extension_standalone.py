"""spikegs._C is built against no torch: it loads on its own, and neither imports torch nor maps
a torch library (libtorch*, libc10*), so one build works with any torch version."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("spikegs._C", reason="the C++ extension spikegs._C is not built")

# The extension's file loaded alone (the spikegs package, which imports torch, left out); prints
# the torch libraries mapped into the process and the torch modules imported.
LOAD_ALONE = """
import importlib.machinery, importlib.util, sys
from pathlib import Path

package = Path(importlib.util.find_spec("spikegs").submodule_search_locations[0])
suffixes = importlib.machinery.EXTENSION_SUFFIXES
path = next(package / f"_C{s}" for s in suffixes if (package / f"_C{s}").is_file())
spec = importlib.util.spec_from_file_location("spikegs._C", path)
spec.loader.exec_module(importlib.util.module_from_spec(spec))
maps = Path("/proc/self/maps").read_text().splitlines()
mapped = {Path(line.split()[5]).name for line in maps if len(line.split()) > 5}
print(sorted(name for name in mapped if name.startswith(("libtorch", "libc10"))))
print(sorted(name for name in sys.modules if name.split(".")[0] == "torch"))
"""


@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="needs Linux's /proc")
def test_the_extension_loads_without_torch():
    done = subprocess.run([sys.executable, "-c", LOAD_ALONE], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split("\n")[:2] == ["[]", "[]"], done.stdout
