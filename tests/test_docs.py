"""The documentation site's promises that a text check can keep (no JAX, no MkDocs build: a few file reads):

* the API pages (``docs/api/*.md``, mkdocstrings' ``:::`` directives) cover every name of every public package's
  ``__all__`` (and, for a package without one, of each public module's ``__all__``);
* no Markdown heading in ``docs/`` carries a date, and no page says "this session": the pages state the current
  state of things, and history lives in git and ``CHANGELOG.md``;
* every file of ``docs/`` that the library or the docs name exists, and every citation of a reference page section
  (``docs/<page>.md §N``) or of a topic (``docs/performance.md, <Topic>``, ``docs/results.md, <Topic>``) resolves to
  a heading of that page;
* docs/performance.md has the marked section that each standing benchmark (``benchmarks/<name>.py --update-docs``)
  rewrites.

``mkdocs build --strict`` (CI, the README's contributing section) checks the rest: links, anchors, docstrings.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
LIBRARY = ("jaxmdp", "agents", "hardness")
#: Packages whose names are not part of the documented API: the jaxlib workarounds are internal, to be deleted
#: when jaxlib is fixed.
INTERNAL = {"jaxmdp.jaxlib_workarounds"}

DATE = re.compile(r"20\d\d-[01]\d")
HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")


def _literal_all(path: Path) -> list[str] | None:
    """The module's ``__all__`` when it is a literal list or tuple of strings, else None."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
            try:
                value = ast.literal_eval(node.value)
            except ValueError:
                return None
            return [str(v) for v in value]
    return None


def _is_private(dotted: str) -> bool:
    return any(part.startswith("_") for part in dotted.split("."))


def public_names() -> dict[str, list[str]]:
    """``{owner: names}``: every public package's ``__all__``; for a package without one, every public module's."""
    owners: dict[str, list[str]] = {}
    for top in LIBRARY:
        for init in sorted((ROOT / top).rglob("__init__.py")):
            package = ".".join(init.parent.relative_to(ROOT).parts)
            if _is_private(package) or any(package == p or package.startswith(p + ".") for p in INTERNAL):
                continue
            names = _literal_all(init)
            if names is not None:
                owners[package] = names
                continue
            for module in sorted(init.parent.glob("*.py")):
                if module.name == "__init__.py" or module.stem.startswith("_"):
                    continue
                names = _literal_all(module)
                if names:
                    owners[f"{package}.{module.stem}"] = names
    return owners


def api_directives() -> list[tuple[str, list[str] | None]]:
    """``(target, members)`` of every ``::: target`` directive of the API pages; ``members`` is the explicit
    ``members:`` list of its options, or None (mkdocstrings then renders the target's ``__all__``)."""
    found = []
    for page in sorted((DOCS / "api").glob("*.md")):
        lines = page.read_text(encoding="utf-8").splitlines()
        for i, line in enumerate(lines):
            if not line.startswith(":::"):
                continue
            target = line[3:].strip()
            members: list[str] | None = None
            j = i + 1
            while j < len(lines) and (not lines[j].strip() or lines[j].startswith(" ")):
                stripped = lines[j].strip()
                if stripped == "members:":
                    members = []
                elif stripped.startswith("members:") and stripped != "members:":
                    members = re.findall(r"[A-Za-z_][A-Za-z0-9_]*", stripped.split(":", 1)[1])
                elif members is not None and stripped.startswith("- "):
                    members.append(stripped[2:].strip())
                elif not stripped and j + 1 < len(lines) and not lines[j + 1].startswith(" "):
                    break
                j += 1
            found.append((target, members))
    return found


def _module_file(dotted: str) -> Path | None:
    """The source file of module or package ``dotted`` of the repository, or None when it names no module."""
    path = ROOT.joinpath(*dotted.split("."))
    for candidate in (path.with_suffix(".py"), path / "__init__.py"):
        if candidate.exists():
            return candidate
    return None


def _is_submodule(owner: str, name: str) -> bool:
    return _module_file(f"{owner}.{name}") is not None


def _rendered(target: str, members: list[str] | None) -> set[str]:
    """The names a ``::: target`` directive renders from ``target``: its ``members`` list, else the module's
    ``__all__`` less the names that are also its submodules (rendered as the module, not as the re-exported object)."""
    if members is not None:
        return set(members)
    source = _module_file(target)
    names = _literal_all(source) if source is not None else None
    return {n for n in names or () if not _is_submodule(target, n)}


def test_the_api_pages_cover_every_public_name():
    directives = api_directives()
    assert directives, "no ::: directive found in docs/api/*.md"
    missing = []
    for owner, names in public_names().items():
        for name in names:
            covered = False
            for target, members in directives:
                if target == owner or target.startswith(owner + "."):
                    # ``::: owner``, ``::: owner.name``, an object re-exported by owner documented where it is
                    # defined (``::: owner.module.name``), a submodule of owner whose ``__all__`` holds the name,
                    # or, for a name that is itself a submodule, a page of its modules.
                    covered = (
                        (target.endswith("." + name) and _module_file(target) is None)
                        or target == f"{owner}.{name}"
                        or (_is_submodule(owner, name) and target.startswith(f"{owner}.{name}."))
                        or name in _rendered(target, members)
                    )
                if covered:
                    break
            if not covered:
                missing.append(f"{owner}.{name}")
    assert not missing, f"public names missing from docs/api/*.md: {missing}"


def _markdown_pages() -> list[Path]:
    return sorted(DOCS.rglob("*.md"))


def _headings(page: Path) -> list[str]:
    out, fenced = [], False
    for line in page.read_text(encoding="utf-8").splitlines():
        if line.lstrip().startswith("```"):
            fenced = not fenced
        m = None if fenced else HEADING.match(line)
        if m:
            out.append(m.group(2))
    return out


def test_no_heading_in_docs_carries_a_date():
    dated = [f"{p.relative_to(ROOT)}: {h}" for p in _markdown_pages() for h in _headings(p) if DATE.search(h)]
    assert not dated, dated


def test_no_page_says_this_session():
    pages = [str(p.relative_to(ROOT)) for p in _markdown_pages() if "this session" in p.read_text(encoding="utf-8")]
    assert not pages, pages


def _joined(path: Path) -> str:
    """The file's text with each line's indentation and comment markers dropped and the lines joined by spaces, so
    that a citation wrapped over two comment or docstring lines reads as one."""
    parts = []
    for line in path.read_text(encoding="utf-8").splitlines():
        parts.append(re.sub(r"^\s*(#:?\s?)?", "", line))
    return " ".join(parts)


def _citing_files() -> list[Path]:
    files = [p for top in LIBRARY for p in sorted((ROOT / top).rglob("*.py"))]
    files += [p for p in _markdown_pages() if "tables" not in p.relative_to(DOCS).parts]
    files.append(ROOT / "README.md")
    return files


PAGE = re.compile(r"\bdocs/[\w/.-]*\w")
SECTION = re.compile(r"docs/(\w+)\.md\s+§(\d+(?:\.\d+)*)")
TOPIC = re.compile(r"docs/(performance|results)\.md,\s+([A-Z][^).;:,\"`\]]*)")


def _section_numbers(page: Path) -> set[str]:
    numbers = set()
    for heading in _headings(page):
        m = re.match(r"(\d+(?:\.\d+)*)\.?(\s|$)", heading)
        if m:
            numbers.add(m.group(1))
    return numbers


def _topic_headings(page: Path) -> set[str]:
    return {h.strip().lower() for h in _headings(page)}


def test_every_docs_citation_resolves_to_a_heading():
    sections: dict[str, set[str]] = {}
    topics: dict[str, set[str]] = {}
    broken = []
    for path in _citing_files():
        text = _joined(path)
        where = str(path.relative_to(ROOT))
        for cited in PAGE.findall(text):
            if not (ROOT / cited).exists():
                broken.append(f"{where}: {cited} (no such file)")
        for page, number in SECTION.findall(text):
            target = DOCS / f"{page}.md"
            if not target.exists():
                broken.append(f"{where}: docs/{page}.md §{number} (no such page)")
                continue
            if page not in sections:
                sections[page] = _section_numbers(target)
            if number not in sections[page]:
                broken.append(f"{where}: docs/{page}.md §{number}")
        for page, topic in TOPIC.findall(text):
            if page not in topics:
                topics[page] = _topic_headings(DOCS / f"{page}.md")
            topic = topic.strip()
            if topic.lower() not in topics[page]:
                broken.append(f"{where}: docs/{page}.md, {topic}")
    assert not broken, "citations without a heading:\n" + "\n".join(sorted(set(broken)))


@pytest.mark.parametrize("page", ["families", "measures", "agents", "benchmark"])
def test_reference_pages_keep_their_numbered_sections(page):
    """The docstrings cite these pages by § number: §1 must still be there, and the numbers must not be reused."""
    numbers = _section_numbers(DOCS / f"{page}.md")
    assert "1" in numbers or "0" in numbers


def test_performance_page_has_a_section_for_every_standing_benchmark():
    """``python benchmarks/<name>.py --update-docs`` rewrites the lines between ``<!-- bench:<name> -->`` and
    ``<!-- /bench:<name> -->`` of docs/performance.md, and refuses to run without them."""
    text = (DOCS / "performance.md").read_text(encoding="utf-8")
    names = [p.stem for p in sorted((ROOT / "benchmarks").glob("*.py")) if not p.stem.startswith("_")]
    assert names, "no standing benchmark in benchmarks/"
    missing = [
        n for n in names
        if f"<!-- bench:{n} -->" not in text or f"<!-- /bench:{n} -->" not in text
        or text.index(f"<!-- bench:{n} -->") > text.index(f"<!-- /bench:{n} -->")
    ]
    assert not missing, f"docs/performance.md has no <!-- bench:NAME --> section for {missing}"
