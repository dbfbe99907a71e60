"""MkDocs hook: MathJax served by the site itself.

The site's equations (``pymdownx.arithmatex``) are typeset by MathJax 3's ``tex-svg`` component,
copied at build time from the pinned wheel ``django-static-mathjax`` (MathJax 3.2.2 unchanged,
requirements-docs.txt) into ``javascripts/mathjax/``: the SVG output needs no font files, and
nothing is fetched from the network when a page is viewed.
"""

from __future__ import annotations

from importlib import resources
from typing import Any

from mkdocs.structure.files import File, Files

TARGET = "javascripts/mathjax/tex-svg.js"


def on_files(files: Files, config: Any) -> Files:
    source = resources.files("mathjax") / "static" / "mathjax" / "es5" / "tex-svg.js"
    files.append(File.generated(config, TARGET, abs_src_path=str(source)))
    return files
