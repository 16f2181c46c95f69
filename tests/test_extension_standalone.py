"""spikegs._C is built against no torch: it loads on its own, and neither imports torch nor maps
a torch library (libtorch*, libc10*), so one build works with any torch version."""

from __future__ import annotations

import os
import shutil
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


def test_a_package_without_its_extension_says_it_is_not_built(tmp_path):
    """The package's Python files without spikegs._C (a checkout's python/ on PYTHONPATH, unbuilt,
    or shadowing an installed copy) raised "cannot import name '_C' from partially initialized
    module 'spikegs' (most likely due to a circular import)": it says the extension is not built
    and how to build it."""
    import spikegs

    package = Path(spikegs.__file__).parent
    shutil.copytree(package, tmp_path / "spikegs", ignore=shutil.ignore_patterns("_C*"))
    done = subprocess.run(
        [sys.executable, "-c", "import spikegs"],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(tmp_path)},
    )
    assert done.returncode == 1
    said = done.stderr.strip().splitlines()[-1]
    assert said.startswith("ImportError: spikegs's C++ extension (spikegs._C) is not built in"), (
        said
    )
    # both options the in-place build needs (INPLACE alone configured, then built no module:
    # the install trial; CMakeLists.txt now refuses it)
    assert "(-DSPIKEGS_PYTHON=ON -DSPIKEGS_INPLACE=ON: docs/install.md)" in said, said
