"""Sphinx extension of the pverosion documentation.

* Generates the API reference (``api/generated/*.rst``): one page per public
  module, documenting what the module defines and listed in its ``__all__``,
  with links to the defining module for names it re-exports.
* The ``pverosion-cli`` directive renders every subcommand of the ``pverosion``
  command line from the argument parser itself.
* A completeness check: after reading, every name in the ``__all__`` of every
  public module, every accessor method and every CLI subcommand must be
  documented, and every gallery example must have produced a figure;
  otherwise the build warns (an error under ``sphinx-build -W``).

What must be documented is computed by :mod:`pverosion_api`.
"""

from __future__ import annotations

import os
from pathlib import Path

from docutils import nodes
from docutils.parsers.rst import Directive
from sphinx.util import logging

from pverosion_api import cli_parsers, index_page, missing_from_reference, module_page, public_modules

logger = logging.getLogger(__name__)


def _write_if_changed(path: Path, text: str) -> None:
    if not path.exists() or path.read_text(encoding="utf-8") != text:
        path.write_text(text, encoding="utf-8")


def generate_api(app) -> None:
    """Write ``api/generated/<module>.rst`` for every public module and their grouped toctree ``contents.txt``."""
    out = Path(app.srcdir) / "api" / "generated"
    out.mkdir(parents=True, exist_ok=True)
    modules = public_modules()
    wanted = {f"{m}.rst" for m in modules}
    for stale in out.glob("*.rst"):
        if stale.name not in wanted:
            stale.unlink()
    for module_name in modules:
        _write_if_changed(out / f"{module_name}.rst", module_page(module_name))
    _write_if_changed(out / "contents.txt", index_page(modules))


class CliDirective(Directive):
    """``pverosion-cli``: one section per subcommand with its ``--help`` text."""

    has_content = False

    def run(self):
        env = self.state.document.settings.env
        old = os.environ.get("COLUMNS")
        os.environ["COLUMNS"] = "100"  # argparse wraps to the terminal: fix the width
        try:
            result = []
            for name, sub in cli_parsers().items():
                section = nodes.section(ids=[f"cli-{name.replace(' ', '-')}"], names=[f"pverosion {name}"])
                section += nodes.title(text=f"pverosion {name}")
                section += nodes.literal_block(text=sub.format_help().rstrip())
                result.append(section)
        finally:
            if old is None:
                del os.environ["COLUMNS"]
            else:
                os.environ["COLUMNS"] = old
        _cli_documented(env).setdefault(env.docname, set()).update(cli_parsers())
        return result


def _cli_documented(env) -> dict[str, set[str]]:
    """Subcommands rendered by the ``pverosion-cli`` directive, by the document rendering them."""
    if not hasattr(env, "pverosion_cli"):
        env.pverosion_cli = {}
    return env.pverosion_cli


def check_completeness(app, env) -> None:
    """Warn about every public name, accessor method, CLI subcommand or example figure left out."""
    for full in missing_from_reference(env.domains["py"].objects):
        logger.warning("API reference: %s is public but not documented", full)
    documented = set().union(*_cli_documented(env).values())
    for name in cli_parsers():
        if name not in documented:
            logger.warning("CLI reference: subcommand 'pverosion %s' is not documented", name)
    gallery = app.config.sphinx_gallery_conf
    for examples, built in zip(gallery["examples_dirs"], gallery["gallery_dirs"]):
        images = Path(app.srcdir) / built / "images"
        for script in sorted(Path(examples).glob("*.py")):
            if not any(images.glob(f"sphx_glr_{script.stem}_[0-9][0-9][0-9].png")):
                logger.warning("gallery: %s produced no figure", script.name)


def _merge_cli(app, env, docnames, other) -> None:
    _cli_documented(env).update({doc: names for doc, names in _cli_documented(other).items() if doc in docnames})


def _purge_cli(app, env, docname) -> None:
    _cli_documented(env).pop(docname, None)


def setup(app):
    app.connect("builder-inited", generate_api)
    app.connect("env-purge-doc", _purge_cli)
    app.connect("env-merge-info", _merge_cli)
    app.connect("env-check-consistency", check_completeness)
    app.add_directive("pverosion-cli", CliDirective)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True, "env_version": 1}


__all__ = ["CliDirective", "check_completeness", "generate_api", "setup"]
