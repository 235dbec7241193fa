"""The documentation covers the package: API reference, CLI reference, gallery, README, licence.

The Sphinx build (``sphinx-build -W``, run by ``.ci/run``) checks the same with the built pages; these
tests need no Sphinx and fail fast.
"""

from __future__ import annotations

import ast
import inspect
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs" / "_ext"))

import pverosion_api  # noqa: E402


def _autodocumented() -> set[str]:
    """Full names that the generated module pages document (not the re-export links)."""
    names = set()
    for module_name in pverosion_api.public_modules():
        page = pverosion_api.module_page(module_name)
        names.update(re.findall(r"^\.\. auto(?:function|class|data):: (\S+)$", page, flags=re.M))
        names.update(f"{module_name}.{name}" for name in re.findall(r"^\.\. py:data:: (\S+)$", page, flags=re.M))
    return names


def _accessor_methods() -> set[str]:
    from pverosion._accessor import ErosionAccessor

    return {f"{pverosion_api.ACCESSOR}.{name}" for name, _ in inspect.getmembers(ErosionAccessor, inspect.isfunction)
            if not name.startswith("_")}


def test_every_public_name_is_documented_where_it_is_defined():
    api_index = (ROOT / "docs" / "api" / "index.md").read_text(encoding="utf-8")
    assert re.search(rf"\.\. autoclass:: {re.escape(pverosion_api.ACCESSOR)}\n\s+:members:", api_index)
    assert pverosion_api.missing_from_reference(_autodocumented() | _accessor_methods()) == []


def test_the_reference_check_reports_what_is_left_out():
    documented = _autodocumented() | _accessor_methods()
    assert "pverosion.api.weather" in documented
    missing = pverosion_api.missing_from_reference(documented - {"pverosion.api.weather",
                                                                 f"{pverosion_api.ACCESSOR}.weather"})
    # pverosion.weather re-exports pverosion.api.weather: both names are reported, and the accessor method
    expected = ["pverosion.weather", "pverosion.api.weather", f"{pverosion_api.ACCESSOR}.weather"]
    assert sorted(missing) == sorted(expected)


def test_every_public_module_has_an_all_and_a_docstring():
    import importlib

    for module_name in pverosion_api.public_modules():
        module = importlib.import_module(module_name)
        assert hasattr(module, "__all__"), module_name
        assert (module.__doc__ or "").strip(), f"{module_name} has no module docstring"


def test_cli_reference_renders_every_subcommand():
    from pverosion.filters import ALL_FILTERS

    assert "```{pverosion-cli}" in (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    commands = set(pverosion_api.cli_parsers())
    assert {f.command_name() for f in ALL_FILTERS} | {"demo", "batch", "warmup", "view", "paraview"} <= commands
    # nested subcommands get their own section, with their options
    assert {"paraview setup", "paraview plugin-path"} <= commands
    assert "--pvpython" in pverosion_api.cli_parsers()["paraview setup"].format_help()


def test_every_example_is_a_titled_gallery_script():
    scripts = sorted((ROOT / "examples").glob("*.py"))
    assert len(scripts) >= 9
    for script in scripts:
        doc = ast.get_docstring(ast.parse(script.read_text(encoding="utf-8")))
        assert doc, f"{script.name}: no docstring (sphinx-gallery needs a title)"
        title, underline = doc.splitlines()[:2]
        assert title.strip() and set(underline.strip()) == {"="} and len(underline.strip()) >= len(title.strip()), \
            f"{script.name}: the docstring must start with a title underlined by '='"
    conf = (ROOT / "docs" / "conf.py").read_text(encoding="utf-8")
    assert '"filename_pattern": r".*\\.py"' in conf  # every example is executed, so its figure is built


def test_readme_is_short_and_keeps_the_two_commands():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) < 150
    assert "pip install . && pverosion demo" in readme
    assert 'pip install ".[test]" && python -m pytest -q tests' in readme
    for section in ("Errors and limits", "ParaView", "Viewing results", "Layout"):
        assert re.search(rf"^## {section}$", readme, flags=re.M), section
    for link in re.findall(r"\]\(((?:docs|examples)/[^)#]*|[A-Z]+\.md|LICENSE)\)", readme):
        if not link.startswith("docs/topics/") or link == "docs/topics/array-names.md":
            assert (ROOT / link).exists(), link


def test_license_matches_pyproject():
    import tomllib

    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    assert project["license"] == "BSD-3-Clause"
    assert project["license-files"] == ["LICENSE"]
    assert (ROOT / "LICENSE").read_text(encoding="utf-8").startswith("BSD 3-Clause License")
    assert set(project["optional-dependencies"]["docs"]) >= {"myst-parser>=4"}


def test_the_repository_speaks_of_the_software_only():
    """No word about the history of the software's development (its work periods); technical uses are fine."""
    try:
        files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout")
    term = "sess" + "ion"  # spelled in two parts so that this file does not match itself
    word = re.compile(rf"\b{term}s?\b", flags=re.I)
    allowed = re.compile(rf"start_new_{term}|scope=\"{term}\"")

    def identifier(line: str, match: re.Match) -> bool:
        """A variable of that name (``x = ...``, ``x.attr``, an argument), not a word of prose."""
        return bool(re.match(r"\s*(=[^=]|\.\w|,|\))", line[match.end():])) or line[:match.start()].endswith(("(", "return "))

    offending = []
    for name in files:
        path = ROOT / name
        if path.suffix in {".png", ".raw", ".ply", ".dem"} or not path.is_file():
            continue
        for number, line in enumerate(path.read_text(encoding="utf-8", errors="ignore").splitlines(), 1):
            if allowed.search(line):
                continue
            if any(not identifier(line, match) for match in word.finditer(line)):
                offending.append(f"{name}:{number}: {line.strip()}")
    assert offending == []
