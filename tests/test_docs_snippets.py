"""The documentation's Python examples run as written: every ```python block of docs/*.md and
docs/howto/*.md, in the order of its page, each page's blocks in one interpreter (a later block
may use what an earlier one built, as a reader following the page does), in a temporary
directory where ``examples/`` is the repository's. A page whose example stops with an error fails
with the block's number and the error. The README's block has its own test (test_readme.py)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
BLOCK = re.compile(r"^```python\n(.*?)^```", flags=re.S | re.M)


def pages() -> list[Path]:
    return sorted(p for p in [*DOCS.glob("*.md"), *DOCS.glob("howto/*.md")] if BLOCK.search(p.read_text()))


def test_the_pages_with_python_examples_are_found():
    """The pages this test runs: the getting-started guide and the how-tos that have examples
    (a page moved or its examples retagged would silently drop out of the test otherwise)."""
    names = {str(p.relative_to(DOCS)) for p in pages()}
    assert {"getting-started.md", "howto/deposit-at-rest.md", "howto/threads.md"} <= names, names


@pytest.mark.parametrize("page", pages(), ids=lambda p: str(p.relative_to(DOCS)))
def test_the_page_s_python_examples_run(page, tmp_path):
    blocks = BLOCK.findall(page.read_text())
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    for k, b in enumerate(blocks):  # a syntax error names its block here
        compile(b, f"{page.name} block {k}", "exec")
    script = "\n".join(f"print('--- block {k}', flush=True)\n{b}" for k, b in enumerate(blocks))
    env = {**os.environ, "MPLBACKEND": "Agg"}
    r = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True, text=True, env=env)
    started = re.findall(r"^--- block (\d+)$", r.stdout, flags=re.M)
    assert r.returncode == 0, f"{page.name}, block {started[-1] if started else 0}: {r.stderr[-1500:]}"
    assert len(started) == len(blocks)
