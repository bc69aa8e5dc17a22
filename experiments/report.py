"""Regenerate the result blocks of the README and docs/results.md from the experiments'
committed summaries.

Every block (in ``README.md`` or ``docs/results.md``, the files of ``DOCUMENTS``)

    <!-- report:KEY -->
    ...generated markdown...
    <!-- /report:KEY -->

is the output of ``readme_section(summary)``, a function of the script
``experiments/STEM.py``, called on ``experiments/reported/KEY.json`` (a copy of the
``results/KEY/summary.json`` the script wrote). KEY is the script's stem, or
``STEM.VARIANT`` for a second configuration of the same script (its results folder is
then ``results/STEM.VARIANT``, given to the script with ``--out``). Scripts are
imported by path and must not run anything at import. A headline block

    <!-- headline:KEY -->
    ...
    <!-- /headline:KEY -->

is the same, from the script's ``headline(summary)``: the one or two lines the README's
*Headline results* quote, the full block being in docs/results.md.

Outside the blocks the documents' result sections may hold prose, but no measured number:
:func:`loose_numbers` flags percentages, durations, ``k/n`` and ``k of n`` counts
there (settings of the method, listed in ``SETTINGS``, excepted). A region the lead
has yet to wire is fenced by ``<!-- TODO report:KEY -->`` ... ``<!-- /TODO -->``; it is
listed as pending, not checked.

    python experiments/report.py             # rewrite the blocks of README.md and docs/results.md
    python experiments/report.py --check     # exit 1 listing stale blocks / loose numbers
    python experiments/report.py --collect   # first copy results/KEY/summary.json
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import argparse
import hashlib
import importlib.util
import json
import re
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BLOCK = re.compile(r"<!-- (?P<kind>report|headline):(?P<key>[\w.-]+) -->\n(?P<body>.*?)"
                   r"<!-- /(?P=kind):(?P=key) -->", re.S)
TODO = re.compile(r"<!-- TODO report:(?P<key>[\w.-]+) -->.*?<!-- /TODO -->", re.S)
#: the documents whose blocks are generated (README.md: the headlines; docs/results.md: the rest)
DOCUMENTS = ("README.md", "docs/results.md")
#: sections (level-2 headings) of those documents that report results: no loose numbers there
RESULT_SECTIONS = ("Headline results", "The method and what we measured", "Gymnasium environments",
                   "Scale-out")
#: a measured-looking number: a percentage, a duration, a ratio "x", "k/n", "k of n"
NUMBER = re.compile(r"(?<![\w.])\d+(?:[.,]\d+)*\s*(?:%|ms\b|s\b|min\b|minutes\b|×)"
                    r"|(?<![\w.])\d+\s*/\s*\d+(?!\w|\.\d)|(?<![\w.])\d+ of \d+(?!\w|\.\d)")
#: settings of the method and bounds asserted by the test suite (not measured results)
#: that look like results to NUMBER
SETTINGS = ("2 ms steps", "1 ms steps", "on at least 99.5 % of random poses")


class ReportError(Exception):
    """A block that cannot be generated (no summary, no script, no readme_section)."""


@dataclass(frozen=True)
class Block:
    key: str
    kind: str  # "report" (readme_section) or "headline" (headline)
    start: int  # offsets of the body in the README text
    end: int
    body: str


def blocks(text: str) -> list[Block]:
    out = [Block(m["key"], m["kind"], m.start("body"), m.end("body"), m["body"]) for m in BLOCK.finditer(text)]
    keys = [f"{b.kind}:{b.key}" for b in out]
    dup = sorted({k for k in keys if keys.count(k) > 1})
    if dup:
        raise ReportError(f"blocks appear twice: {', '.join(dup)}")
    return out


def _module(stem: str, root: Path, function: str = "readme_section"):
    path = root / "experiments" / f"{stem}.py"
    if not path.is_file():
        raise ReportError(f"report:{stem}: no script {path.relative_to(root)}")
    exp = str(path.parent)
    if exp not in sys.path:
        sys.path.insert(0, exp)  # the scripts import _common
    name = f"_report_{stem}_{hashlib.sha1(str(path).encode()).hexdigest()[:8]}"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, path)
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod  # dataclasses look their module up while the class is built
        spec.loader.exec_module(mod)
    mod = sys.modules[name]
    if not callable(getattr(mod, function, None)):
        raise ReportError(f"report:{stem}: experiments/{stem}.py defines no {function}(summary)")
    return mod


def section(key: str, root: Path = ROOT, kind: str = "report") -> str:
    """The generated markdown of block ``key`` (ends with a newline); ``kind``
    ``"headline"``: the script's ``headline(summary)``."""
    path = root / "experiments" / "reported" / f"{key}.json"
    if not path.is_file():
        raise ReportError(f"report:{key}: no summary {path.relative_to(root)} "
                          f"(run the script, then `python experiments/report.py --collect`)")
    summary = json.loads(path.read_text())
    if kind == "headline":
        return _module(key.split(".")[0], root, "headline").headline(summary).strip("\n") + "\n"
    text = _module(key.split(".")[0], root).readme_section(summary).strip("\n")
    return text + measured_at(summary) + "\n"


def measured_at(summary: dict) -> str:
    """The line naming the code a block's numbers came from (the summary's git commit,
    taken when the run started): a reader re-running the command on newer code can tell
    whether a difference is the code's."""
    prov = summary.get("provenance")
    commit = prov.get("commit") if isinstance(prov, dict) else None
    if not commit:
        return ""
    clean = commit.removesuffix("-dirty")
    dirty = " with uncommitted changes" if clean != commit else ""
    return f"\n\n<sub>Measured at commit `{clean}`{dirty}.</sub>"


def render(text: str, root: Path = ROOT) -> tuple[str, list[str], list[str]]:
    """(the document with every block that can be generated regenerated, keys of the
    blocks that changed, errors of the blocks that cannot be generated -- left as they
    are)."""
    out, stale, errors, pos = [], [], [], 0
    for b in blocks(text):
        try:
            new = section(b.key, root, b.kind)
        except ReportError as e:
            errors.append(str(e))
            new = b.body
        if new != b.body:
            stale.append(b.key if b.kind == "report" else f"{b.kind}:{b.key}")
        out += [text[pos:b.start], new]
        pos = b.end
    out.append(text[pos:])
    return "".join(out), stale, errors


def _result_sections(text: str) -> list[tuple[int, int]]:
    heads = [(m.start(), m.group(1).strip()) for m in re.finditer(r"^## (.+)$", text, re.M)]
    spans = []
    for i, (start, title) in enumerate(heads):
        if title in RESULT_SECTIONS:
            spans.append((start, heads[i + 1][0] if i + 1 < len(heads) else len(text)))
    return spans


def loose_numbers(text: str) -> list[str]:
    """``"line N: ...number..."`` for each measured-looking number in a result section
    outside the generated blocks and the TODO regions."""
    masked = text
    for rx in (BLOCK, TODO):
        masked = rx.sub(lambda m: re.sub(r"[^\n]", " ", m.group(0)), masked)
    for s in SETTINGS:
        masked = masked.replace(s, " " * len(s))
    found = []
    for start, end in _result_sections(masked):
        for m in NUMBER.finditer(masked, start, end):
            line = masked.count("\n", 0, m.start()) + 1
            found.append(f"line {line}: {m.group(0)!r} in {text.splitlines()[line - 1].strip()[:80]!r}")
    return found


def pending(text: str) -> list[str]:
    return [m["key"] for m in TODO.finditer(text)]


def documents(root: Path = ROOT) -> list[Path]:
    """The generated documents present under ``root`` (``DOCUMENTS``)."""
    return [root / d for d in DOCUMENTS if (root / d).is_file()]


def check(doc: Path | None = None, root: Path = ROOT) -> list[str]:
    """Problems with ``doc`` (default: every document of ``DOCUMENTS``): stale blocks,
    blocks that cannot be generated, loose numbers in the result sections. Empty when
    the documents match the summaries."""
    if doc is None:
        return [f"{d.relative_to(root)}: {p}" for d in documents(root) for p in check(d, root)]
    text = doc.read_text()
    try:
        _, stale, problems = render(text, root)
    except ReportError as e:  # duplicate blocks
        return [str(e)]
    problems += [f"stale block {k if ':' in k else 'report:' + k} (run python experiments/report.py)"
                 for k in stale]
    problems += [f"number outside a generated block, {s}" for s in loose_numbers(text)]
    return problems


def collect(doc: Path | None = None, root: Path = ROOT) -> list[str]:
    """Copy ``results/KEY/summary.json`` to ``experiments/reported/KEY.json`` for every
    block of ``doc`` (default: every document) whose results are present; returns the
    keys copied."""
    keys = {b.key for d in ([doc] if doc else documents(root)) for b in blocks(d.read_text())}
    done = []
    for key in sorted(keys):
        src = root / "results" / key / "summary.json"
        if src.is_file():
            json.loads(src.read_text())  # a broken file stops here, before it is committed
            dst = root / "experiments" / "reported" / f"{key}.json"
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(src, dst)
            done.append(key)
    return done


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--check", action="store_true", help="exit 1 if a document is stale (writes nothing)")
    p.add_argument("--collect", action="store_true", help="first copy results/KEY/summary.json files")
    p.add_argument("--doc", action="append", default=None,
                   help=f"a document to regenerate or check (repeatable; default: {', '.join(DOCUMENTS)})")
    a = p.parse_args(argv)
    docs = [Path(d) for d in a.doc] if a.doc else documents()
    try:
        if a.collect:
            print("collected: " + (", ".join(k for d in docs for k in collect(d)) or "nothing"))
        if a.check:
            problems = []
            for d in docs:
                for k in pending(d.read_text()):
                    print(f"{d.name}: pending (not checked): TODO report:{k}")
                problems += [f"{d.name}: {s}" for s in check(d)]
            for s in problems:
                print(s)
            return 1 if problems else 0
        errors = []
        for d in docs:
            text = d.read_text()
            new, stale, errs = render(text)
            if stale:
                d.write_text(new)
            print(f"{d.name}: regenerated: " + (", ".join(stale) or "nothing (up to date)"))
            for s in loose_numbers(new):
                print(f"warning: {d.name}: number outside a generated block, {s}")
            errors += [f"{d.name}: {e}" for e in errs]
        for e in errors:
            print(f"error: {e}", file=sys.stderr)
        return 2 if errors else 0
    except ReportError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
