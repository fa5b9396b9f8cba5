"""promp/, library/ and the data types never import pydrake (DESIGN.md: data flows one way)."""
import subprocess
import sys

CODE = r"""
import importlib, pkgutil, sys
import drake_skills.promp, drake_skills.library
names = ["drake_skills.data.demonstration", "drake_skills.data.lasa"]
for pkg in (drake_skills.promp, drake_skills.library):
    names += [m.name for m in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + ".")]
for n in names:
    importlib.import_module(n)
assert "pydrake" not in sys.modules, [m for m in sys.modules if m.startswith("pydrake")]
print(len(names))
"""


def test_core_modules_do_not_import_pydrake():
    out = subprocess.run([sys.executable, "-c", CODE], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    # promp: basis, gaussian, interaction, preprocessing; library: batch, incremental, storage at least
    assert int(out.stdout.split()[-1]) >= 9, out.stdout
