"""Every command the documentation quotes names something that exists, and every image it shows
is there: a reader who copies a command from docs/, README.md, studies/README.md or
benchmarks/README.md finds its script, its `granrs` subcommand (and validation case or run file),
its Python module or its cargo bench or test target; every ``![..](path)`` and ``{figure}`` of
those pages, and every link to a data file, resolves. Commands are read from code only: fenced
blocks that are not Python, indented blocks and inline code spans, at the start of the code or
after ``&&``, ``;`` or ``|``. Placeholders in capitals (``FILE.toml``, ``NAME``) are not checked."""

from __future__ import annotations

import argparse
import importlib.util
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
GENERATED = {"reference/cli.md", "reference/keys.md", "reference/options.md"}


def pages() -> list[Path]:
    found = [p for p in DOCS.rglob("*.md") if not {"_build", "auto_examples"} & set(p.relative_to(DOCS).parts)]
    found = [p for p in found if str(p.relative_to(DOCS)) not in GENERATED]
    return sorted(found) + [ROOT / "README.md", ROOT / "studies" / "README.md", ROOT / "benchmarks" / "README.md"]


def page_id(p: Path) -> str:
    return str(p.relative_to(ROOT))


FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```", flags=re.S | re.M)


def code_of(text: str) -> list[str]:
    """The command-like code of a Markdown page: non-Python fenced blocks (each logical line, with
    backslash continuations joined), indented blocks and inline spans (a span may wrap lines)."""
    out: list[str] = []
    for lang, body in FENCE.findall(text):
        if lang.strip().startswith("{") and not lang.strip().startswith("{code"):
            continue  # MyST directives ({figure}, {toctree}): their paths are checked as images
        if lang.strip() in ("python", "py", "toml", "json", "text"):
            continue
        out += body.replace("\\\n", " ").splitlines()
    rest = FENCE.sub("", text)
    for block in re.findall(r"(?:^(?: {4}|\t)\S.*\n?)+", rest, flags=re.M):
        prev = rest[: rest.index(block)].rstrip(" ").endswith("\n\n") or rest.index(block) == 0
        if prev:
            out += block.replace("\\\n", " ").splitlines()
    inline = re.sub(r"^(?: {4}|\t)\S.*$", "", rest, flags=re.M)
    out += [s.replace("\n", " ") for s in re.findall(r"`([^`]+)`", inline)]
    return [line.strip() for line in out if line.strip()]


def commands(code: str) -> list[list[str]]:
    """The commands of one piece of code, as word lists (a leading ``$ `` and a shell comment
    dropped)."""
    parts = re.split(r"\s*(?:&&|;|\|)\s*", re.sub(r"(^|\s)#.*$", "", code))
    return [p.split() for p in (q.removeprefix("$ ").strip() for q in parts) if p]


def expand(word: str) -> list[str]:
    """Brace expansion of one word: a/b_{x,y}.toml -> a/b_x.toml, a/b_y.toml."""
    m = re.search(r"\{([^{}]*,[^{}]*)\}", word)
    if not m:
        return [word]
    return [w for alt in m.group(1).split(",") for w in expand(word[: m.start()] + alt + word[m.end() :])]


def placeholder(word: str) -> bool:
    stem = Path(word).stem
    return bool(re.fullmatch(r"[A-Z][A-Z0-9_]*", stem)) or word.startswith(("DIR", "OUT", "FILE", "$"))


def cli_names() -> tuple[set[str], set[str]]:
    sys.path.insert(0, str(DOCS / "_ext"))
    try:
        import granrs_docs
    finally:
        sys.path.pop(0)
    parser = granrs_docs.cli_parser()
    subs = {n for a in parser._actions if isinstance(a, argparse._SubParsersAction) for n in a.choices}
    from granrs.validation import CASES

    return subs, set(CASES) | {"list"}


def problems_of(page: Path) -> list[str]:
    text = page.read_text()
    subs, cases = cli_names()
    bad: list[str] = []
    for code in code_of(text):
        for words in commands(code):
            head = words[0]
            if head in (".venv/bin/python", "python", "python3") and len(words) > 1:
                if words[1] == "-m" and len(words) > 2:
                    if importlib.util.find_spec(words[2]) is None:
                        bad.append(f"no module {words[2]}: {code}")
                elif words[1].endswith(".py") and not placeholder(words[1]):
                    for w in expand(words[1]):
                        if not (ROOT / w).is_file():
                            bad.append(f"no script {w}: {code}")
            elif head in ("granrs", ".venv/bin/granrs") and len(words) > 1 and not words[1].startswith("-"):
                sub = words[1]
                if sub not in subs:
                    bad.append(f"no granrs subcommand {sub!r}: {code}")
                elif sub == "validate" and len(words) > 2 and not words[2].startswith("-"):
                    if words[2] not in cases and not placeholder(words[2]):
                        bad.append(f"no validation case {words[2]!r}: {code}")
                elif sub in ("run", "sweep") and len(words) > 2 and words[2].endswith(".toml"):
                    for w in expand(words[2]):
                        if not placeholder(w) and not (ROOT / w).is_file():
                            bad.append(f"no run file {w}: {code}")
            elif head == "cargo" and len(words) > 1 and words[1] in ("bench", "test"):
                for flag, folder in (("--bench", "benches"), ("--test", "tests")):
                    if flag in words and words.index(flag) + 1 < len(words):
                        name = words[words.index(flag) + 1]
                        if not placeholder(name) and not list(ROOT.glob(f"rust/*/{folder}/{name}.rs")):
                            bad.append(f"no cargo {flag[2:]} target {name!r}: {code}")
    for target in shown_files(text):
        if not (page.parent / target).exists():
            bad.append(f"no file {target} (shown or linked)")
    return bad


def shown_files(text: str) -> list[str]:
    """Images (``![..](path)``, ``{figure} path``, ``{image} path``) and links to data files."""
    found = re.findall(r"!\[[^\]]*\]\(([^)\s]+)\)", text)
    found += re.findall(r"^```\{(?:figure|image)\}\s+(\S+)", text, flags=re.M)
    found += [
        t
        for t in re.findall(r"(?<!!)\[[^\]]*\]\(([^)\s#]+)\)", text)
        if not re.match(r"[a-z]+:", t) and re.search(r"\.(png|svg|csv|json|txt|npz|toml)$", t)
    ]
    return found


def test_the_pages_and_their_commands_are_found(tmp_path):
    """The test reads the pages it should (a page moved out of its reach would pass silently),
    finds commands of every kind it checks, and a wrong name fails it."""
    names = {page_id(p) for p in pages()}
    assert {"docs/validation.md", "docs/benchmarks.md", "docs/howto/deposit-at-rest.md", "README.md"} <= names
    words = [w for p in pages() for c in code_of(p.read_text()) for w in commands(c)]
    heads = {(w[0], w[1]) for w in words if len(w) > 1}
    assert {("granrs", "run"), ("granrs", "validate"), ("cargo", "bench")} <= heads, heads
    assert any(w[:1] == ["python"] and w[1].startswith("studies/") for w in words)
    page = tmp_path / "probe.md"
    page.write_text(
        "Run `python studies/no_such_study.py --ny 8`, then `granrs validate no-such-case`,\n"
        "`granrs frobnicate`, `cargo bench -p granrs-core --bench nope`.\n\n![x](img/nope.png)\n"
    )
    bad = problems_of(page)
    assert len(bad) == 5, bad


@pytest.mark.parametrize("page", pages(), ids=page_id)
def test_every_quoted_command_and_shown_image_exists(page):
    assert problems_of(page) == []
