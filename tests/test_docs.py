"""The documentation against the tree: the README's length and set-up commands, the code
map against the modules, every relative link, and the benchmark results against the
files they are generated from."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
LAYOUT = ROOT / "docs" / "layout.md"
RESULTS_MD = ROOT / "benchmarks" / "RESULTS.md"
PACKAGES = ("radiosity", "fitting", "display")
README_MAX_LINES = 200

LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
MODULE = re.compile(r"`((?:" + "|".join(PACKAGES) + r")/[\w/]*\.py)`")
NUMBER = re.compile(r"(?<![\w.])-?\d+(?:\.\d+)?")


def markdown_files():
    return [README, *sorted((ROOT / "docs").glob("*.md")), ROOT / "benchmarks" / "README.md", RESULTS_MD]


def package_modules():
    """Every .py file of the three packages, as a path relative to the root (vendored
    non-Python data such as display/web is not a module)."""
    return {p.relative_to(ROOT).as_posix() for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")}


def slug(heading):
    """GitHub's anchor for a markdown heading."""
    text = heading.strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path):
    found = set()
    in_code = False
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("```"):
            in_code = not in_code
        elif not in_code and line.startswith("#"):
            found.add(slug(line.lstrip("#")))
    return found


def links(path):
    """(target, line number) of every markdown link outside code blocks."""
    out = []
    in_code = False
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if line.startswith("```"):
            in_code = not in_code
            continue
        if not in_code:
            out += [(m.group(1), number) for m in LINK.finditer(line)]
    return out


def test_readme_fits_on_a_screen():
    lines = README.read_text(encoding="utf-8").count("\n")
    assert lines <= README_MAX_LINES, f"README.md has {lines} lines, more than {README_MAX_LINES}: move detail to docs/"


def test_ci_runs_the_readmes_test_command():
    """.ci/run runs command 2 of the README's set-up verbatim."""
    readme = README.read_text(encoding="utf-8")
    block = re.search(r"## Set-up: two commands.*?```sh\n(.*?)```", readme, re.S)
    assert block, "README.md has no '## Set-up: two commands' section with a sh block"
    commands = [line for line in block.group(1).splitlines() if line.strip() and not line.startswith("#")]
    assert len(commands) == 2, f"the set-up block should hold two commands, found {commands}"
    assert commands[0].endswith("&& vlights demo")
    ci = [line for line in (ROOT / ".ci" / "run").read_text().splitlines() if line.strip() and not line.startswith("#")]
    assert commands[1] in ci, f".ci/run does not run the README's command 2 verbatim: {commands[1]!r}"


def test_code_map_names_every_module_and_only_modules():
    named = set(MODULE.findall(LAYOUT.read_text(encoding="utf-8")))
    modules = package_modules()
    missing = sorted(modules - named)
    stale = sorted(named - modules)
    message = []
    if missing:
        message.append("docs/layout.md does not name these modules: " + ", ".join(missing))
    if stale:
        message.append("docs/layout.md names modules that do not exist: " + ", ".join(stale))
    assert not message, "; ".join(message)


def test_relative_links_resolve():
    broken = []
    for path in markdown_files():
        for target, line in links(path):
            if re.match(r"[a-z][a-z0-9+.-]*:", target):  # http:, https:, mailto:
                continue
            file_part, _, anchor = target.partition("#")
            where = (path.parent / file_part).resolve() if file_part else path
            name = f"{path.relative_to(ROOT)}:{line}: {target}"
            if not where.exists():
                broken.append(f"{name} (no such file)")
            elif anchor and where.suffix == ".md" and anchor not in anchors(where):
                broken.append(f"{name} (no heading #{anchor} in {where.relative_to(ROOT)})")
    assert not broken, "broken links:\n" + "\n".join(broken)


def test_slug_is_githubs_anchor():
    assert slug("## Ground truth: `vlights truth`".lstrip("#")) == "ground-truth-vlights-truth"
    assert slug(" The glTF export: `scene.glb` (format `vlights.fit.gltf`, version 2)") == (
        "the-gltf-export-sceneglb-format-vlightsfitgltf-version-2"
    )


def load_report():
    spec = importlib.util.spec_from_file_location("benchmarks_report", ROOT / "benchmarks" / "report.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_results_md_is_what_the_results_files_give():
    report = load_report()
    expected = report.render(ROOT / "benchmarks" / "results")
    assert RESULTS_MD.read_text(encoding="utf-8") == expected, (
        "benchmarks/RESULTS.md is not what benchmarks/results/*.jsonl give: run python benchmarks/report.py"
    )


def test_report_changes_when_a_result_changes(tmp_path):
    """The report reads the files: a changed row changes RESULTS.md, so the test above can fail."""
    report = load_report()
    source = ROOT / "benchmarks" / "results"
    for path in source.glob("*.jsonl"):
        (tmp_path / path.name).write_text(path.read_text(encoding="utf-8"), encoding="utf-8")
    before = report.render(tmp_path)
    fit_speed = tmp_path / "fit_speed.jsonl"
    fit_speed.write_text(fit_speed.read_text(encoding="utf-8").replace('"median_s": 9.196', '"median_s": 99.196'))
    after = report.render(tmp_path)
    assert before != after and "99.20" in after and "99.20" not in before


def readme_key_numbers():
    """(bullet text without its links, anchor) of each bullet of the README's key numbers."""
    text = README.read_text(encoding="utf-8")
    section = re.search(r"## Key measured numbers\n(.*?)\n## ", text, re.S)
    assert section, "README.md has no '## Key measured numbers' section"
    bullets = re.split(r"\n- ", "\n" + section.group(1).split("\n- ", 1)[1])
    out = []
    for bullet in filter(None, (b.strip() for b in bullets)):
        results = [m.group(1) for m in LINK.finditer(bullet) if m.group(1).startswith("benchmarks/RESULTS.md#")]
        assert results, f"a key number without a link to a RESULTS.md section: {bullet!r}"
        out.append((LINK.sub("", bullet), results[0].partition("#")[2]))
    return out


def results_sections():
    sections, current = {}, None
    for line in RESULTS_MD.read_text(encoding="utf-8").splitlines():
        if line.startswith("## "):
            current = slug(line[3:])
            sections[current] = []
        elif current:
            sections[current].append(line)
    return {k: "\n".join(v) for k, v in sections.items()}


def test_readme_key_numbers_are_in_the_sections_they_link_to():
    """Each clause of a key-number bullet (split at ';' and ':'): a lone number must appear
    in the linked section, several numbers together on one line of it (one table row)."""
    sections = results_sections()
    bullets = readme_key_numbers()
    assert len(bullets) >= 4
    absent = []
    for text, anchor in bullets:
        assert anchor in sections, f"README links RESULTS.md#{anchor}, which has no such section"
        lines = [set(NUMBER.findall(line)) for line in sections[anchor].splitlines()]
        for clause in re.split(r"[;:]", text):
            numbers = set(NUMBER.findall(clause))
            if numbers and not any(numbers <= line for line in lines):
                absent.append(f"{sorted(numbers)} of {clause.strip()!r} not on one line of #{anchor}")
    assert not absent, "README key numbers not in RESULTS.md:\n" + "\n".join(absent)


@pytest.mark.parametrize("page", sorted(p.name for p in (ROOT / "docs").glob("*.md")))
def test_every_manual_page_is_linked_from_the_readme(page):
    assert f"(docs/{page})" in README.read_text(encoding="utf-8"), f"README.md does not link docs/{page}"
