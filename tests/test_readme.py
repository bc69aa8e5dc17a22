"""The README's Python tour runs as written (against a fresh database folder)."""

import json
import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


@pytest.mark.slow
def test_readme_python_tour_runs(tmp_path, monkeypatch):
    text = README.read_text()
    tour = text[text.index("From Python:"):]
    code = re.search(r"```python\n(.*?)```", tour, re.S).group(1)
    monkeypatch.setenv("GRASPSIM_DB", str(tmp_path / "db"))
    ns: dict = {}
    exec(compile(code, "README.md", "exec"), ns)  # noqa: S102 - our own README
    assert ns["T_obj_wrist"].shape == (10, 4, 4)
    assert len(ns["result"].map) > 0 and len(ns["known"].map) > 0
    assert ns["known"].status.value == "complete" and len(ns["known"].parts) == 2


# ------------------------------------------------------------------ generated results
def _report():
    import importlib.util
    import sys

    path = README.parent / "experiments" / "report.py"
    spec = importlib.util.spec_from_file_location("_graspsim_report", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def test_readme_results_match_the_committed_summaries():
    """Every generated block equals readme_section() of its committed JSON, and the
    result sections hold no measured number outside the blocks (run
    ``python experiments/report.py`` after re-running an experiment)."""
    problems = _report().check()
    assert not problems, "\n".join(problems)


def _fake_repo(tmp_path, body: str):
    (tmp_path / "experiments" / "reported").mkdir(parents=True)
    (tmp_path / "experiments" / "exp_x.py").write_text(
        "def readme_section(s):\n    return f\"`{s['command']}`: {s['k']}/{s['n']} succeed\\n\"\n")
    (tmp_path / "experiments" / "reported" / "exp_x.json").write_text(
        json.dumps({"command": "python experiments/exp_x.py", "k": 3, "n": 4}))
    readme = tmp_path / "README.md"
    readme.write_text("# t\n\n## The method and what we measured\n\n" + body + "\n## Other\n\n50 % here is fine\n")
    return readme


def test_report_regenerates_blocks_and_flags_stale_ones(tmp_path):
    report = _report()
    readme = _fake_repo(tmp_path, "Prose.\n\n<!-- report:exp_x -->\nold 2/4\n<!-- /report:exp_x -->\n")
    new, stale, errors = report.render(readme.read_text(), tmp_path)
    assert stale == ["exp_x"] and errors == []
    assert "`python experiments/exp_x.py`: 3/4 succeed\n<!-- /report:exp_x -->" in new
    assert any("stale block report:exp_x" in p for p in report.check(readme, tmp_path))
    readme.write_text(new)
    assert report.check(readme, tmp_path) == []
    assert report.render(new, tmp_path) == (new, [], [])
    # a variant block reads its own JSON with the same script's readme_section
    (tmp_path / "experiments" / "reported" / "exp_x.b.json").write_text(
        json.dumps({"command": "python experiments/exp_x.py --b", "k": 1, "n": 2}))
    text, stale, _ = report.render(new + "<!-- report:exp_x.b -->\n<!-- /report:exp_x.b -->\n", tmp_path)
    assert stale == ["exp_x.b"] and "--b`: 1/2 succeed" in text
    missing = "<!-- report:exp_y -->\nkept\n<!-- /report:exp_y -->\n"
    assert report.render(missing, tmp_path)[0] == missing
    assert "no summary experiments/reported/exp_y.json" in report.render(missing, tmp_path)[2][0]


def test_report_flags_numbers_outside_blocks(tmp_path):
    report = _report()
    readme = _fake_repo(tmp_path, "Grasps succeed 98.9 % of 1344, in 2.0 s; 15/15 and 12 of 40.\n"
                                  "A 5 mm scan, 11° steps, μ = 0.5 and 2 ms steps are settings.\n"
                                  "<!-- TODO report:later -->\n77 % pending\n<!-- /TODO -->\n")
    found = report.loose_numbers(readme.read_text())
    assert [f.split("'")[1] for f in found] == ["98.9 %", "2.0 s", "15/15", "12 of 40"]
    assert report.pending(readme.read_text()) == ["later"]


def test_report_collect_copies_present_results(tmp_path):
    report = _report()
    readme = _fake_repo(tmp_path, "<!-- report:exp_x -->\n<!-- /report:exp_x -->\n"
                                  "<!-- report:exp_z -->\n<!-- /report:exp_z -->\n")
    (tmp_path / "results" / "exp_x").mkdir(parents=True)
    (tmp_path / "results" / "exp_x" / "summary.json").write_text('{"command": "c", "k": 1, "n": 1}')
    assert report.collect(readme, tmp_path) == ["exp_x"]
    assert json.loads((tmp_path / "experiments" / "reported" / "exp_x.json").read_text())["k"] == 1


def test_report_checks_headlines_and_every_document(tmp_path):
    """README headline blocks come from the script's headline(); check() with no file
    reads every document of DOCUMENTS (README.md and docs/results.md)."""
    report = _report()
    readme = _fake_repo(tmp_path, "")
    with open(tmp_path / "experiments" / "exp_x.py", "a") as f:
        f.write("def headline(s):\n    return f\"{s['k']} of {s['n']} succeed\"\n")
    readme.write_text("# t\n\n## Headline results\n\n<!-- headline:exp_x -->\nold\n<!-- /headline:exp_x -->\n")
    (tmp_path / "docs").mkdir()
    results = tmp_path / "docs" / "results.md"
    results.write_text("# r\n\n## The method and what we measured\n\n"
                       "<!-- report:exp_x -->\nold\n<!-- /report:exp_x -->\n")
    problems = report.check(root=tmp_path)
    assert any(p.startswith("README.md: stale block headline:exp_x") for p in problems), problems
    assert any(p.startswith("docs/results.md: stale block report:exp_x") for p in problems), problems
    for doc in (readme, results):
        doc.write_text(report.render(doc.read_text(), tmp_path)[0])
    assert "<!-- headline:exp_x -->\n3 of 4 succeed\n<!-- /headline:exp_x -->" in readme.read_text()
    assert report.check(root=tmp_path) == []
    results.write_text(results.read_text() + "\nAnd 12 of 40 loose.\n")
    assert [p.split(",")[0] for p in report.check(root=tmp_path)] == [
        "docs/results.md: number outside a generated block"]


def test_readme_is_short_with_contents():
    """The README stays a front page (the results live in docs/results.md)."""
    text = README.read_text()
    assert len(text.splitlines()) <= 350 and "## Contents" in text
    assert "<!-- report:" not in text, "full result blocks belong in docs/results.md"
    for link in re.findall(r"\]\((docs/[^)#]+)", text):
        assert (README.parent / link).is_file(), link


def test_docs_the_code_cites_exist():
    """Every ``docs/NAME.md`` the package, tests or experiments cite exists, and every
    ``docs/design.md §N`` names a section of it."""
    root = README.parent
    heads = {int(n) for n in re.findall(r"^## (\d+)\. ", (root / "docs" / "design.md").read_text(), re.M)}
    cited = 0
    for folder in ("graspsim", "tests", "experiments"):
        for path in (root / folder).rglob("*.py"):
            if path == Path(__file__).resolve():
                continue
            text = path.read_text()
            for doc in re.findall(r"\bdocs/([\w-]+\.md)", text):
                assert (root / "docs" / doc).is_file(), f"{path.relative_to(root)} cites docs/{doc}"
            for n in re.findall(r"docs/design\.md\s+§(\d+)", text):
                assert int(n) in heads, f"{path.relative_to(root)} cites docs/design.md §{n}"
                cited += 1
            assert "DESIGN.md" not in text, f"{path.relative_to(root)} cites DESIGN.md (now docs/design.md)"
    assert cited >= 10
