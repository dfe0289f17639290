"""The project's own physics page (docs/physics.md) is what the code cites: every equation label
([MR 15.10.16], [T 3.82]) a docstring, comment, config or the README cites is listed on it, every
section the code names exists, and nothing points at texts outside the repository; and every
Python block of the README and docs/ runs."""

import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "physics.md"
LABEL = re.compile(r"\[(?:MR|T)(?: Fig\.)? [0-9][0-9.\-]*[0-9]\]")


def _sources():
    files = [p for d in ("rbenvs", "agents", "tests", "configs") for p in (ROOT / d).rglob("*") if p.suffix in (".py", ".yml", ".yaml", ".md")]
    pages = [p for p in (ROOT / "docs").glob("*.md") if p != PAGE]
    return [p for p in files + pages + [ROOT / "README.md", ROOT / "Makefile", ROOT / "CHANGELOG.md"] if p.is_file()]


def _label_table() -> set[str]:
    text = PAGE.read_text()
    table = text[text.index("## 5. Equation labels"):text.index("## 6. Sources")]
    return {m.group(0) for line in table.splitlines() if line.startswith("| [") for m in [LABEL.match(line[2:])] if m}


def test_every_cited_label_is_on_the_physics_page():
    table = _label_table()
    assert len(table) >= 30
    cited = {}
    for path in _sources():
        for m in LABEL.finditer(path.read_text()):
            cited.setdefault(m.group(0), path.relative_to(ROOT))
    assert len(cited) >= 30  # (the code does cite them: a broken pattern would find none)
    missing = {label: str(where) for label, where in cited.items() if label not in table}
    assert not missing, f"labels cited but not listed in docs/physics.md §5: {missing}"


def test_physics_page_sections_named_by_the_code_exist():
    headings = set(re.findall(r"^## (\d+)\. ", PAGE.read_text(), flags=re.M))
    assert {"1", "2", "3", "4", "5", "6"} <= headings
    named = 0
    for path in _sources():
        text = path.read_text()
        for m in re.finditer(r"(\S*)physics\.md`?((?: §\d+(?:, §\d+)*)?)", text):
            if path == ROOT / "tests" / "test_docs.py":
                continue
            beside = path.parent == PAGE.parent  # (a page in docs/ names it by its own folder)
            assert m.group(1).endswith("docs/") or beside, f"{path.relative_to(ROOT)}: {m.group(0)!r} is not docs/physics.md"
            for section in re.findall(r"§(\d+)", m.group(2)):
                assert section in headings, f"{path.relative_to(ROOT)} cites docs/physics.md §{section}, which does not exist"
                named += 1
    assert named >= 40


def test_no_reference_to_texts_outside_the_repository():
    pattern = re.compile(r"seed 2\b|seed 1,|seed §|seeds/|shared/|\(1[0-9]\.\d+\.\d+\)|\(3\.\d{2,3}\)")
    offenders = [f"{p.relative_to(ROOT)}: {m.group(0)}" for p in _sources() if p != ROOT / "tests" / "test_docs.py" for m in pattern.finditer(p.read_text())]
    assert not offenders, offenders


def test_sources_are_full_citations():
    sources = PAGE.read_text().split("## 6. Sources")[1]
    for needle in ("Marsden and T. S. Ratiu, *Introduction to Mechanics and Symmetry*", "Jellett, *A Treatise on the Theory of Friction*",
                   "Rauch-Wojciechowski", "Leine and Ch. Glocker"):
        assert needle in sources
    entries = [e for e in sources.split("\n- ")[1:]]
    assert all(re.search(r"1[89]\d\d|20\d\d", e) for e in entries), "every source carries its year"


def _python_blocks(path: pathlib.Path) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", path.read_text(), flags=re.M | re.S)


PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def test_the_pages_have_python_blocks():
    assert sum(len(_python_blocks(p)) for p in PAGES) >= 5


@pytest.mark.parametrize("page", [p for p in PAGES if _python_blocks(p)], ids=lambda p: p.name)
def test_every_python_block_of_the_readme_and_docs_runs(page):
    """Each page's Python blocks, in order, in one namespace (a later block may use an earlier
    one's names), as a reader would paste them; their asserts check what the text says."""
    namespace = {"__name__": "__docs__"}
    for block in _python_blocks(page):
        exec(compile(block, str(page), "exec"), namespace)
