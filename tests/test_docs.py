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
    files = [
        p
        for d in ("rbenvs", "agents", "tests", "configs")
        for p in (ROOT / d).rglob("*")
        if p.suffix in (".py", ".yml", ".yaml", ".md")
    ]
    pages = [p for p in (ROOT / "docs").glob("*.md") if p != PAGE]
    return [
        p
        for p in files + pages + [ROOT / "README.md", ROOT / "Makefile", ROOT / "CHANGELOG.md"]
        if p.is_file()
    ]


def _label_table() -> set[str]:
    text = PAGE.read_text()
    table = text[text.index("## 5. Equation labels") : text.index("## 6. Sources")]
    return {
        m.group(0)
        for line in table.splitlines()
        if line.startswith("| [")
        for m in [LABEL.match(line[2:])]
        if m
    }


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
            assert m.group(1).endswith("docs/") or beside, (
                f"{path.relative_to(ROOT)}: {m.group(0)!r} is not docs/physics.md"
            )
            for section in re.findall(r"§(\d+)", m.group(2)):
                assert section in headings, (
                    f"{path.relative_to(ROOT)} cites docs/physics.md §{section}, which does not "
                    "exist"
                )
                named += 1
    assert named >= 40


def test_no_reference_to_texts_outside_the_repository():
    pattern = re.compile(
        r"seed 2\b|seed 1,|seed §|seeds/|shared/|\(1[0-9]\.\d+\.\d+\)|\(3\.\d{2,3}\)"
    )
    offenders = [
        f"{p.relative_to(ROOT)}: {m.group(0)}"
        for p in _sources()
        if p != ROOT / "tests" / "test_docs.py"
        for m in pattern.finditer(p.read_text())
    ]
    assert not offenders, offenders


def test_sources_are_full_citations():
    sources = PAGE.read_text().split("## 6. Sources")[1]
    for needle in (
        "Marsden and T. S. Ratiu, *Introduction to Mechanics and Symmetry*",
        "Jellett, *A Treatise on the Theory of Friction*",
        "Rauch-Wojciechowski",
        "Leine and Ch. Glocker",
    ):
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
    """Each of a page's Python blocks on its own, in a namespace of its own, as a reader who
    copies one block would run it; their asserts check what the text says."""
    for block in _python_blocks(page):
        exec(compile(block, str(page), "exec"), {"__name__": "__docs__"})


# --- figures written by the commands (rbenvs.docblocks), commands that parse ---------------------

FENCE = re.compile(r"^\s*(`{3,})(\S*)\s*$")


def _fenced_blocks(text: str) -> list[tuple[str, int]]:
    """``(language, offset)`` of every fenced block's opening line."""
    found, open_fence, offset = [], None, 0
    for line in text.splitlines(keepends=True):
        m = FENCE.match(line)
        if m:
            if open_fence is None:
                open_fence = m.group(1)
                found.append((m.group(2), offset))
            elif not m.group(2) and len(m.group(1)) >= len(open_fence):
                open_fence = None
        offset += len(line)
    return found


def test_every_figure_block_is_written_by_a_command():
    """A fenced block without a language (a figure, a command's output) lies inside an
    ``rbenvs:output`` block, which only ``--docs`` writes; illustrations say ``text``."""
    from rbenvs.docblocks import _BLOCK

    loose = []
    for page in PAGES:
        text = page.read_text()
        spans = [(m.start(), m.end()) for m in _BLOCK.finditer(text)]
        for lang, at in _fenced_blocks(text):
            if lang == "" and not any(a <= at < b for a, b in spans):
                loose.append(f"{page.relative_to(ROOT)}:{text[:at].count(chr(10)) + 1}")
    assert not loose, (
        "figure blocks not written by a command (wrap them in <!-- rbenvs:output CMD --> ... <!-- "
        f"rbenvs:end -->): {loose}"
    )


def _written_blocks():
    from rbenvs.docblocks import blocks

    return [(page, key, body) for page in PAGES for key, body in blocks(page.read_text())]


def test_the_written_blocks_name_their_command_date_and_machine():
    written = _written_blocks()
    assert len(written) >= 8
    for page, key, body in written:
        assert re.match(rf"`{re.escape(key)}` \(20\d\d-\d\d-\d\d, \d+ cores, .+\):\n\n", body), (
            page.name,
            key,
            body[:200],
        )


class _Parsed(Exception):
    """Raised by argparse's parse_args once the arguments parsed: the command line is valid."""


def _parses(command: str, monkeypatch) -> None:
    """Parse ``command`` with the command's own parser, stopping before it runs."""
    import argparse
    import shlex

    argv = shlex.split(command)
    prog, args = argv[0], argv[1:]
    original = argparse.ArgumentParser.parse_args

    def parse_only(self, args=None, namespace=None):
        original(self, args, namespace)
        raise _Parsed

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", parse_only)
    from rbenvs.cli import main as rbenvs_main

    mains = {"rbenvs": rbenvs_main}
    if prog.startswith("rbenvs-"):
        pytest.importorskip("stable_baselines3")
        from rbenvs_agents import cli

        mains |= {
            "rbenvs-train": cli.train_main,
            "rbenvs-eval": cli.eval_main,
            "rbenvs-results": cli.results_main,
            "rbenvs-sweep": cli.sweep_main,
        }
    assert prog in mains, f"unknown command {prog!r} in {command!r}"
    with pytest.raises(_Parsed):
        mains[prog](args)


def _commands_in_text():
    """Every complete command of the README and docs: the written blocks' command lines, the
    lines of ``bash`` blocks and inline code spans that start with a command (synopses with
    ``[...]``, ``{...}`` or ``...`` are templates, not commands)."""
    from rbenvs.docblocks import _BLOCK

    found = []
    for page in PAGES:
        text = _BLOCK.sub("", page.read_text())  # (a command's output names no commands to run)
        for block in re.findall(r"^ *```bash\n(.*?)^ *```", text, flags=re.M | re.S):
            # a here-document is a program fed to the command before it, not commands
            block = re.sub(r"<<'?(\w+)'?\n.*?^\1$", "", block, flags=re.M | re.S)
            for line in block.splitlines():
                command = line.split("#")[0].strip()
                if command:
                    found.append((page.name, command))
        for span in re.findall(r"`([^`\n]+)`", text):
            if span.startswith("pip install ") or (
                re.match(
                    r"(rbenvs|rbenvs-train|rbenvs-eval|rbenvs-results|rbenvs-sweep|make|python -m "
                    r"rl_zoo3) ",
                    span,
                )
                and not re.search(r"[\[\]{}]|\.\.\.|PATH|NAME|DIR\b", span)
            ):
                found.append((page.name, span))
    for page, key, _ in _written_blocks():
        found.append((page.name, key))
    return sorted(set(found))


def test_the_pages_name_commands():
    commands = [c for _, c in _commands_in_text()]
    assert len(commands) >= 20 and any(c.startswith("rbenvs-results") for c in commands)


@pytest.mark.parametrize(
    "where,command", _commands_in_text(), ids=lambda x: x[:60] if isinstance(x, str) else x
)
def test_every_command_in_the_docs_is_one_the_project_accepts(where, command, monkeypatch):
    """Each command of the pages, as written: ``make`` targets exist, ``pip install`` asks for
    extras that exist (and the pinned torch), and every ``rbenvs`` command line parses with its
    own parser (the cheap ones run in their own tests; the long ones by their authors with
    ``--docs``)."""
    import shlex

    argv = shlex.split(command)
    if argv[0].endswith("/bin/pip"):  # a venv's own pip (the Ray job's)
        argv = ["pip", *argv[1:]]
    if argv[:3] == ["python3", "-m", "venv"] or argv[:2] == ["python", "-"]:
        assert len(argv) >= 2, (
            command
        )  # the standard library's venv; python reading a here-document
    elif argv[:3] == ["python", "-m", "rbenvs_agents.rllib"]:
        # needs the ray extra (its own venv: tests/test_ray.py runs it); here: the module and its
        # main exist
        assert "def main(" in (ROOT / "agents" / "rllib.py").read_text(), command
    elif argv[0] == "make":
        targets = set(re.findall(r"^([a-z][a-z-]*):", (ROOT / "Makefile").read_text(), flags=re.M))
        assert set(argv[1:]) <= targets, command
    elif argv[:2] == ["pip", "install"]:
        import tomllib

        extras = set(
            tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
        )
        for spec in argv[2:]:
            if spec == "-e":
                continue
            m = re.match(r"^(?:\.|rbenvs)(?:\[([a-z,]+)\])?$", spec)
            if m:
                assert set((m.group(1) or "").split(",")) - {""} <= extras, command
            else:
                assert spec == "torch==2.13.0", command
    elif argv[:3] == ["python", "-m", "rl_zoo3.train"]:
        # the zoo's own command line: tests/test_ecosystem.py runs it; here its env and file exist
        import rbenvs

        options = dict(zip(argv[3::2], argv[4::2]))
        assert options["--env"] in rbenvs.ENVIRONMENTS and options["--gym-packages"] == "rbenvs", (
            command
        )
        assert (ROOT / options["--conf-file"]).is_file(), command
    else:
        _parses(command, monkeypatch)


def test_docs_flag_writes_the_output_into_the_named_block(tmp_path, capsys):
    from rbenvs.docblocks import run_with_docs, split_docs_flag

    assert split_docs_flag(["a", "--docs", "p.md", "b"]) == (["a", "b"], "p.md")
    assert split_docs_flag(["--docs=p.md"]) == ([], "p.md")
    page = tmp_path / "page.md"
    page.write_text(
        "before\n<!-- rbenvs:output prog x 'a b' -->\nold\n<!-- rbenvs:end -->\nafter\n"
        "<!-- rbenvs:output prog table -->\n<!-- rbenvs:end -->\n"
    )

    def body(argv):
        print("figures of", argv)
        return 0

    assert run_with_docs("prog", body, ["x", "a b", "--no-progress", "--docs", str(page)]) == 0
    text = page.read_text()
    assert (
        "old" not in text and text.startswith("before\n") and text.endswith("<!-- rbenvs:end -->\n")
    )
    assert re.search(
        r"`prog x 'a b'` \(20\d\d-\d\d-\d\d, \d+ cores, .*\):\n\n```\nfigures of \['x', 'a b', "
        r"'--no-progress'\]\n```\n",
        text,
    )

    def table(argv):
        print("| a | b |\n|---|---|\n| 1 | 2 |")
        return 0

    assert run_with_docs("prog", table, ["table", "--docs", str(page)]) == 0
    assert (
        "\n| a | b |\n|---|---|\n| 1 | 2 |\n<!-- rbenvs:end -->" in page.read_text()
    )  # Markdown stays Markdown

    def bullets(argv):
        print("- one\n- two")
        return 0

    assert run_with_docs("prog", bullets, ["table", "--docs", str(page)]) == 0
    assert "):\n\n- one\n- two\n<!-- rbenvs:end -->" in page.read_text()  # a Markdown list too
    before = page.read_text()
    with pytest.raises(ValueError, match="no block for `prog other`"):
        run_with_docs("prog", body, ["other", "--docs", str(page)])  # refused before it runs
    assert run_with_docs("prog", lambda argv: 1, ["table", "--docs", str(page)]) == 1
    assert page.read_text() == before  # a failed run writes nothing


def test_the_readme_headline_is_made_from_the_records():
    """The README's headline figures are `rbenvs headline`'s output from the records the
    measuring commands wrote: a measuring command run again without the headline made anew
    fails here, naming the command that mends it."""
    from rbenvs.docblocks import find_block
    from rbenvs.headline import headline

    m = find_block((ROOT / "README.md").read_text(), "rbenvs headline")
    assert m is not None, "README.md has no `rbenvs headline` block"
    shown = m.group(2).split("\n\n", 1)[1].strip()
    assert shown == headline(ROOT), (
        "README.md's headline is stale: run `rbenvs headline --docs README.md`"
    )


def test_headline_counts_what_the_records_say(tmp_path):
    import json

    from rbenvs.headline import headline

    with pytest.raises(
        ValueError,
        match=(
            "docs/verify.json is missing: it is written by `rbenvs verify --json docs/verify.json`"
        ),
    ):
        headline(tmp_path)
    docs = tmp_path / "docs"
    docs.mkdir()
    check = {"system": "free_body", "passed": True}
    (docs / "verify.json").write_text(
        json.dumps(
            [
                check,
                check | {"passed": False},
                check | {"system": "tippe_top", "passed": False, "applies": False},
            ]
        )
    )
    row = {
        "scene": None,
        "num_envs": 64,
        "single_ratio_to_pendulum": 0.4,
        "ratio_to_cartpole": 2.0,
        "compiled_over_numpy": 5.0,
    }
    (docs / "throughput.json").write_text(
        json.dumps(
            {
                "tasks": [
                    row | {"id": "rbenvs/FreeRigidBody-v0", "task": "spin"},
                    row
                    | {
                        "id": "rbenvs/TippeTop-v0",
                        "task": "invert",
                        "single_ratio_to_pendulum": 3.0,
                    },
                ]
            }
        )
    )
    rec = {"task": "spin", "seeds": 3, "success_mean": 1.0}
    (docs / "results.json").write_text(
        json.dumps(
            [
                rec | {"scene": "default", "agent": "analytic"},
                rec | {"scene": "default", "agent": "PPO"},
                rec
                | {
                    "scene": "tippe_hold",
                    "task": "hold",
                    "agent": "zero action",
                    "success_mean": 0.0,
                },
            ]
        )
    )
    lines = headline(tmp_path).splitlines()
    assert (
        "1 of 2 checks pass, on free_body " in lines[0]
    )  # (a row that does not apply is not counted)
    assert (
        "free body 0.40; tippe top 3.00." in lines[1]
        and "free body spin 2.00x" in lines[1]
        and "tippe top 5.0-5.0x" in lines[1]
    )
    assert (
        "learned agents on 1 of 2 scenes, 3 seeds each" in lines[2]
        and "`default` PPO 100% (analytic 100%)" in lines[2]
    )
    assert "no learned agent yet on `tippe_hold` (hold)" in lines[2]
