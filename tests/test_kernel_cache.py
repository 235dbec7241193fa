"""numba's cache of the kernels follows every kernel source file (pverosion.kernels._cache_stamp)."""

from __future__ import annotations

import inspect
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pverosion
from pverosion.kernels import _cache_stamp
from pverosion.kernels._cache_stamp import KernelTreeLocator, sources_digest

PACKAGE = Path(pverosion.__file__).resolve().parent

# one small kernel, called once; prints whether numba loaded it from the cache or compiled it
PROBE = """
import json
import numpy as np
from pverosion.kernels._search import lower_bound
lower_bound(np.arange(8), 0, 8, 5)
stats = lower_bound.stats
print(json.dumps({"hits": sum(stats.cache_hits.values()), "misses": sum(stats.cache_misses.values()),
                  "locator": type(lower_bound._cache._impl.locator).__name__}))
"""


def _copy_package(root: Path) -> Path:
    shutil.copytree(PACKAGE, root / "pverosion", ignore=shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc"))
    return root / "pverosion"


def _probe(root: Path, cache: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(root), "NUMBA_CACHE_DIR": str(cache)}
    env.pop("NUMBA_CACHE_LOCATOR_CLASSES", None)
    done = subprocess.run([sys.executable, "-c", PROBE], env=env, cwd=root, capture_output=True, text=True,
                          timeout=300, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_a_change_to_another_kernel_file_recompiles_a_cached_kernel(tmp_path):
    package = _copy_package(tmp_path)
    cache = tmp_path / "cache"
    first = _probe(tmp_path, cache)
    assert first["locator"] == "KernelTreeLocator"
    assert first["misses"] == 1 and first["hits"] == 0
    assert _probe(tmp_path, cache)["hits"] == 1  # unchanged sources: loaded from the cache
    # a module the kernel does not live in (the scatter-add's constants); numba alone would keep the cached code
    scatter = package / "kernels" / "_scatter.py"
    scatter.write_text(scatter.read_text() + "\n# changed\n")
    again = _probe(tmp_path, cache)
    assert again["misses"] == 1 and again["hits"] == 0
    assert _probe(tmp_path, cache)["hits"] == 1


def test_sources_digest_follows_content_and_names_not_place(tmp_path):
    a = _copy_package(tmp_path / "a") / "kernels"
    b = _copy_package(tmp_path / "b") / "kernels"
    assert sources_digest(a) == sources_digest(b) == sources_digest()
    (b / "_search.py").write_text((b / "_search.py").read_text() + " ")
    assert sources_digest(a) != sources_digest(b)
    (b / "_search.py").write_text((a / "_search.py").read_text())
    assert sources_digest(a) == sources_digest(b)
    (b / "_search.py").rename(b / "_search2.py")
    assert sources_digest(a) != sources_digest(b)


def test_only_kernel_functions_get_the_tree_stamp():
    from pverosion._runtime import threads_for  # a function of the package outside the kernels

    assert KernelTreeLocator.from_function(threads_for, inspect.getfile(threads_for)) is None

    from pverosion.kernels._search import lower_bound

    locator = lower_bound._cache._impl.locator
    assert isinstance(locator, KernelTreeLocator)
    own, tree = locator.get_source_stamp()
    assert tree == sources_digest()
    assert own == locator._inner.get_source_stamp()
    assert locator.get_cache_path() == locator._inner.get_cache_path()


def test_install_is_idempotent():
    locators = _cache_stamp._numba_locators()
    _cache_stamp.install()
    _cache_stamp.install()
    assert locators.count(KernelTreeLocator) == 1
    assert locators[0] is KernelTreeLocator
