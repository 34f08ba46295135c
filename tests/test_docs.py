"""Docs that cannot rot (issue 26): README.md and docs/*.md against the code and the results.

* docs/results.md and the README's headline block are exactly what benchmarks/results_page.py makes
  of benchmarks/*/results/*.json; the headline is a table of at most 12 lines whose figures are the JSON's;
* every command line shown in a fenced code block (and every ``vcprep``/``vctrain`` command in an
  inline code span) names a real command whose flags appear in that command's ``--help``; fenced
  commands also take the number of arguments the command takes; ``make`` targets and benchmark
  scripts (and their flags) exist;
* the cheap fenced commands whose inputs exist (the shipped examples, presets) are run for real,
  in document order, in a scratch folder that holds ``examples/``;
* every relative Markdown link resolves to a file, and its ``#anchor`` to a heading.

No network, no dataset outside the repository.
"""
from __future__ import annotations

import glob
import importlib.util
import json
import os
import re
import shlex
import subprocess
from functools import lru_cache
from pathlib import Path

import pytest
from typer.testing import CliRunner

from conftest import BIN

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SHELL_LANGS = {"", "sh", "bash", "shell", "console"}
PATH_SUFFIXES = {".yaml", ".yml", ".txt", ".json", ".png", ".jpg", ".csv", ".npy", ".pt", ".md"}
OUTPUT_OPTIONS = {"-o", "--out"}
# (prog, subcommand path) run for real when every input they name exists: fast, on a few frames
RUNNABLE = {("vcprep", ("cameras",)), ("vcprep", ("camera", "show")), ("vcprep", ("camera", "design")),
            ("vcprep", ("warp",)), ("vcprep", ("complete",)), ("vcprep", ("vp",)),
            ("vcprep", ("store", "show")), ("vcprep", ("store", "info")), ("vcprep", ("store", "verify")),
            ("vcprep", ("figure", "warp")), ("vcprep", ("figure", "completion")), ("vcprep", ("figure", "vp")),
            ("vcprep", ("figure", "fov")), ("vcprep", ("figure", "footprints"))}


def _results_page():
    spec = importlib.util.spec_from_file_location("results_page", ROOT / "benchmarks" / "results_page.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


# ---------------------------------------------------------------- generated results


def test_results_page_matches_the_json():
    rp = _results_page()
    assert (ROOT / "docs" / "results.md").read_text() == rp.render_page(), \
        "docs/results.md differs from benchmarks/*/results/*.json: run `make docs`"


def test_readme_headline_matches_the_json():
    rp = _results_page()
    readme = (ROOT / "README.md").read_text()
    assert rp.with_headline(readme, rp.render_headline()) == readme, \
        "README.md's headline differs from benchmarks/*/results/*.json: run `make docs`"


def _result(folder: str, stem: str) -> dict:
    return json.loads((ROOT / "benchmarks" / folder / "results" / f"{stem}.json").read_text())


def _headline_table(readme: str) -> tuple[list[str], dict[str, list[str]]]:
    """(the lines between the headline markers, the table's body rows by their regime cell)."""
    block = readme.split("<!-- headline:", 1)[1].split("-->", 1)[1].split("<!-- end of headline -->")[0]
    lines = block.strip("\n").splitlines()
    rows = [[c.strip() for c in ln.strip().strip("|").split("|")] for ln in lines if ln.startswith("|")][2:]
    return lines, {r[0]: r for r in rows}


def test_headline_is_a_short_table_of_both_regimes_and_the_shipped_model():
    """At most 12 lines; a table whose rows give, as the JSON has them, one training camera (as_shipped),
    several cameras merged (multi_camera_median, worst held-out cameras named), several calibrated
    cameras merged (calibrated_loo_lite0fpn) and the shipped model (the model that ships, beside its
    virtual-camera twin trained on every development set: ship_geometry); which model to use and when
    the virtual camera pays; a link to the full figures."""
    lines, rows = _headline_table((ROOT / "README.md").read_text())
    assert len(lines) <= 12, lines
    assert [r[:18] for r in rows] == ["one training camer", "several cameras me", "several calibrated",
                                      "the shipped model,"], list(rows)
    one, several, calibrated, shipped = rows.values()
    a = _result("other_cameras", "as_shipped")["headline"]
    assert f"**{a['real_within_minus_resize']:+.1f} ± {a['real_within_minus_resize_std']:.1f}**" in one[2]
    assert one[1].startswith("the virtual camera") and "3 seeds" in one[2]
    assert all(name in one[3] for name in ("Cityscapes", "IDD-Lite", "KITTI", "BDD100K", "LUMS"))
    m = _result("other_cameras", "multi_camera_median")["headline"]
    assert f"**{m['loo_within_minus_resize']:+.1f} ± {m['loo_within_minus_resize_std']:.1f}**" in several[2]
    assert several[1] == "resize" and f"{len(m['seeds'])} seeds" in several[2]
    assert f"worst IDD-Lite {m['loo_within_minus_resize_idd']:+.1f} ± " in several[3]
    assert f"BDD100K {m['loo_within_minus_resize_bdd']:+.1f} ± " in several[3]
    c = _result("other_cameras", "calibrated_loo_lite0fpn")
    assert f"**{c['headline']['loo_within_minus_resize']:+.1f} ± {c['headline']['loo_within_minus_resize_std']:.1f}**" in calibrated[2]
    assert calibrated[1].startswith("the virtual camera") and f"{len(c['seeds'])} seeds" in calibrated[2]
    assert f"worst CamVid {c['headline']['loo_within_minus_resize_camvid']:+.1f}" in calibrated[3]
    ship = _result("what_a_user_gets", "ship_mix_six")  # issue 82: the model shipped, beside the ones shipped before
    h = ship["headline"]
    assert "models/road-all" in shipped[0] and shipped[1] == "resize"
    assert (f"held-out mean **{h['mean_six']:.1f}** (1 seed, {ship['epochs']} epochs) against {h['mean_road-street']:.1f} "
            f"for `road-street` and {h['mean_shipped']:.1f} for `road-multicamera`, shipped before") in shipped[2]
    loo = _result("other_cameras", "ship_loo")["headline"]
    if loo.get("six_mean") is not None and loo.get("today_mean") is not None:  # the held-out-camera verdict
        assert f"{loo['six_mean']:.1f} against {loo['today_mean']:.1f}" in shipped[2]
    assert f"{len(ship['splits'])} held-out splits" in shipped[3]
    text = " ".join(lines)
    assert "a lite0fpn trained on CamVid, Cityscapes, KITTI, IDD-Lite, BDD100K, LUMS with the frames read as they are" in text
    assert (f"`road-street` is {-loo['six-30_minus_four-30']:.1f} ahead on held-out datasets" in text
            and f"`road-multicamera` {h['shipped_bdd'] - h['six_bdd']:.1f} on BDD100K's dashcams" in text)
    assert f"used on others ({a['real_within_minus_resize']:+.1f} ± " in text
    assert "[docs/results.md](docs/results.md)" in text


def test_check_fails_on_a_headline_without_a_regime_figure_or_over_12_lines(tmp_path, capsys):
    rp = _results_page()
    assert rp.main(["--check"]) == 0, capsys.readouterr().err
    readme = (ROOT / "README.md").read_text()
    m = _result("other_cameras", "multi_camera_median")["headline"]
    several = f"{m['loo_within_minus_resize']:+.1f} ± {m['loo_within_minus_resize_std']:.1f}"
    cut = "\n".join(ln.replace(several, "-") if ln.startswith("| several") else ln
                    for ln in rp.render_headline().splitlines())
    (tmp_path / "README.md").write_text(rp.with_headline(readme, cut))
    assert rp.main(["--check", "--readme", str(tmp_path / "README.md")]) == 1
    err = capsys.readouterr().err
    assert f"leaves out the 'several cameras merged' figure ({several}" in err, err
    (tmp_path / "README.md").write_text(rp.with_headline(readme, rp.render_headline() + "\n\nOne more.\n"))
    assert rp.main(["--check", "--readme", str(tmp_path / "README.md")]) == 1
    n = len(rp.render_headline().strip("\n").splitlines()) + 2
    assert f"the headline has {n} lines, at most 12" in capsys.readouterr().err


def test_results_page_says_where_each_readme_figure_comes_from():
    """The page's first section names, per figure the README states, its results file and script;
    the README states each as that table does (whitespace aside)."""
    rp = _results_page()
    page = (ROOT / "docs" / "results.md").read_text()
    section = page.split("## Where the README's figures come from\n", 1)[1].split("\n## ", 1)[0]
    readme = " ".join((ROOT / "README.md").read_text().split())
    files = rp.result_files()
    data = rp.load_all()
    for what, parts, name in rp.headline.readme_figures(data):
        path = files[name.rsplit(".", 1)[0]].with_name(name)
        assert path.is_file(), name
        assert f"[`{rp.rel(path)}`]" in section and ", ".join(parts) in section, what
        for part in parts:
            assert part in readme, (what, part)
    assert "benchmarks/what_a_user_gets/ship_mix.py" in section and "benchmarks/other_cameras/as_shipped.py" in section


def test_results_page_lists_every_json_with_its_facts():
    page = (ROOT / "docs" / "results.md").read_text()
    for p in sorted((ROOT / "benchmarks").glob("*/results/*.json")):
        assert f"\n## {p.stem}\n" in page
        section = page.split(f"\n## {p.stem}\n", 1)[1].split("\n## ", 1)[0]
        for fact in ("| command |", "| date |", "| machine |"):
            assert fact in section, (p.name, fact)
        assert f"| file | [`{p.relative_to(ROOT)}`]" in section  # beside the question it answers


def test_results_sit_beside_the_script_that_writes_them_and_name_it():
    """Every results JSON has its script in the same question folder, or in that question's archive
    (benchmarks/archive/<question>/: a closed study, issue 79), and a recorded command runs that script
    by its path (an archived one's: the path it ran from, before it moved)."""
    rp = _results_page()
    for p in sorted((ROOT / "benchmarks").glob("*/results/*.json")):
        script = rp.script_for(p)
        question = p.parent.parent
        assert script is not None and script.parent in (question, question.parent / "archive" / question.name), p
        argv = json.loads(p.read_text()).get("command", "").split()
        if argv:
            ran = argv[argv[0] == "python"]  # (after a leading "python")
            assert ran in (rp.rel(script), rp.rel(question / script.name)), (p.name, argv)


def test_archived_studies_are_listed_with_their_answer():
    """benchmarks/archive/README.md names every archived script, and no live folder still holds one."""
    archive = ROOT / "benchmarks" / "archive"
    readme = (archive / "README.md").read_text()
    scripts = sorted(archive.glob("*/*.py"))
    assert len(scripts) >= 15
    for s in scripts:
        assert f"`{s.name}`" in readme and f"## {s.parent.name}/" in readme, s
        assert not (ROOT / "benchmarks" / s.parent.name / s.name).exists(), s


def benchmark_scripts() -> list[str]:
    """Every benchmark script, by its repository path: ``benchmarks/<question>/<name>.py`` (not the shared
    ``measure/`` package, not a folder's ``__init__.py``)."""
    return sorted(str(p.relative_to(ROOT)) for p in (ROOT / "benchmarks").glob("*/*.py")
                  if p.parent.name != "measure" and p.name != "__init__.py")


def test_every_benchmark_script_is_in_the_development_index():
    """docs/development.md's benchmark index (the commands by folder and the paragraph after them) names
    every benchmark script by its path (issue 79: nine were missing)."""
    page = (ROOT / "docs" / "development.md").read_text()
    scripts = benchmark_scripts()
    assert len(scripts) > 20 and "benchmarks/speed/warp.py" in scripts  # (the closed studies: benchmarks/archive/)
    assert [s for s in scripts if s not in page] == []


def test_results_page_generator_is_deterministic_and_generic(tmp_path):
    """A JSON the generator has no table for gets one from its headline, with its recorded facts."""
    rp = _results_page()
    (tmp_path / "newbench.json").write_text('{"headline": {"ratio": 1.25, "n": 3}, "date": "2026-01-02", '
                                            '"command": "benchmarks/speed/newbench.py --x 1", "machine": "x86_64, 2 cores"}')
    page = rp.render_page([tmp_path])
    assert page == rp.render_page([tmp_path])
    assert "| ratio | 1.25 |" in page and "| n | 3 |" in page
    assert "| date | 2026-01-02 |" in page and "`benchmarks/speed/newbench.py --x 1`" in page and "x86_64, 2 cores" in page


def test_results_page_says_when_a_figure_was_measured_on_an_older_library(tmp_path):
    """Issue 81: a ratio measured on OpenCV 5.0 sat on the page beside 5.1 figures without a word;
    a result on an older OpenCV / numpy / torch than another result here now says so."""
    rp = _results_page()
    (tmp_path / "old.json").write_text('{"headline": {"ratio": 1.05}, "cv2": "5.0.0", "numpy": "2.4.6"}')
    (tmp_path / "new.json").write_text('{"headline": {"ratio": 2.1}, "opencv": "5.1.0", "torch": "2.13.0+cpu"}')
    page = rp.render_page([tmp_path])
    new, old = page.split("## new")[1].split("## old")  # (files in name order)
    assert "| versions | measured on OpenCV 5.0.0 (newest in these results: 5.1.0)" in old
    assert "versions" not in new and "numpy" not in old.split("| versions |")[1].split("\n")[0]
    assert rp.version_key("2.13.0+cpu") == (2, 13, 0) and rp.version_key("4.14.0") < rp.version_key("5.1.0")


# ---------------------------------------------------------------- command lines in the docs


def fenced_blocks(text: str) -> list[tuple[str, str]]:
    """(language, body) of every fenced code block."""
    return [(m.group(1).strip(), m.group(2)) for m in re.finditer(r"^```([^\n]*)\n(.*?)^```", text, re.S | re.M)]


def command_lines(body: str) -> list[str]:
    """Shell lines of a block with ``\\`` continuations joined."""
    out, cur = [], ""
    for line in body.splitlines():
        if line.rstrip().endswith("\\"):
            cur += line.rstrip()[:-1] + " "
            continue
        out.append(cur + line)
        cur = ""
    return [ln.strip() for ln in out + ([cur] if cur else []) if ln.strip()]


def pipeline(line: str) -> list[list[str]]:
    """The simple commands of a line (split at |, &&, ||, ;), comments dropped."""
    try:
        tokens = shlex.split(line, comments=True)
    except ValueError:
        return []
    cmds, cur = [], []
    for t in tokens:
        if t in ("|", "&&", "||", ";"):
            cmds.append(cur)
            cur = []
        else:
            cur.append(t)
    return [c for c in cmds + [cur] if c]


def shown_commands() -> list[tuple[str, str, list[str], bool]]:
    """(page, line, argv, fenced) of every vcprep/vctrain/make/benchmark command shown."""
    found = []
    for page in PAGES:
        text = page.read_text()
        for lang, body in fenced_blocks(text):
            if lang not in SHELL_LANGS:
                continue
            for line in command_lines(body):
                for argv in pipeline(line):
                    found.append((page.name, line, argv, True))
        prose = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
        for span in re.findall(r"`([^`\n]+)`", prose):
            if re.match(r"(vcprep|vctrain) ", span):
                for argv in pipeline(span):
                    found.append((page.name, span, argv, False))
    return found


COMMANDS = shown_commands()


@lru_cache(maxsize=None)
def help_of(prog: str, path: tuple[str, ...]) -> str:
    if prog == "vcprep":
        from vcprep.cli import app
    else:
        from vctrain.cli import app
    res = CliRunner().invoke(app, [*path, "--help"], env={"COLUMNS": "200"}, prog_name=prog)
    assert res.exit_code == 0, (prog, path, res.output)
    return res.output


def section(help_text: str, name: str) -> list[str]:
    lines, inside = [], False
    for ln in help_text.splitlines():
        if re.match(r"^\S.*:$", ln):
            inside = ln.strip() == f"{name}:"
            continue
        if inside:
            lines.append(ln)
    return lines


def resolve(prog: str, args: list[str]) -> tuple[tuple[str, ...], list[str]]:
    """The subcommand path named by ``args`` (checked against --help) and the arguments after it."""
    path: tuple[str, ...] = ()
    while True:
        names = [m.group(1) for ln in section(help_of(prog, path), "Commands")
                 if (m := re.match(r"^\s{2}(\S+)\s", ln + " "))]
        if not names:
            return path, args
        if args and is_placeholder(args[0]):  # `vcprep figure …`: a family of commands
            return path, []
        assert args and args[0] in names, f"'{prog} {' '.join(path)}' has no command '{args[0] if args else ''}'"
        path, args = path + (args[0],), args[1:]


@lru_cache(maxsize=None)
def signature(prog: str, path: tuple[str, ...]) -> tuple[dict[str, bool], list[tuple[str, bool, bool]]]:
    """``{option: takes a value}`` and ``[(argument, variadic, required)]`` from the command's --help."""
    text = help_of(prog, path)
    options: dict[str, bool] = {"--help": False}
    for ln in section(text, "Options"):
        m = re.match(r"^\s{2}(-[^\s<].*?)(?:\s{2,}|$)", ln)
        if not m:
            continue
        head = m.group(1)
        takes = "<" in head
        for name in re.findall(r"(?<![\w-])(--?[A-Za-z][\w-]*)", head.split("<")[0]):
            options[name] = takes
    arguments, cur = [], None
    for ln in section(text, "Arguments"):
        m = re.match(r"^\s{2}(\w[\w-]*)(\.\.\.)?\s", ln)
        if m:
            cur = [m.group(1), bool(m.group(2)), False]
            arguments.append(cur)
        if cur is not None and "[required]" in ln:
            cur[2] = True
    return options, [tuple(a) for a in arguments]


def split_args(options: dict[str, bool], args: list[str], where: str,
               fenced: bool = True) -> tuple[list[tuple[str, str | None]], list[str]]:
    """(options used with their values, positionals); an unknown option fails naming ``where``. Prose
    may name an option alone (`vctrain predict --prior`); a command line must give its value."""
    used, positional, i = [], [], 0
    while i < len(args):
        a = args[i].strip("[]")
        if a.startswith("-") and len(a) > 1 and not re.match(r"-\d", a):
            name, _, inline = a.partition("=")
            assert name in options, f"{where}: '{name}' is not an option of this command (see its --help)"
            value = inline or None
            if options[name] and not inline:
                assert i + 1 < len(args) or not fenced, f"{where}: '{name}' needs a value"
                value = args[i + 1] if i + 1 < len(args) else None
                i += 1
            used.append((name, value))
        elif a:
            positional.append(a)
        i += 1
    return used, positional


def is_placeholder(token: str) -> bool:
    return "..." in token or "…" in token or bool(re.fullmatch(r"[A-Z][A-Z_]*", token)) or token.startswith("$")


def check_cli(prog: str, argv: list[str], fenced: bool, where: str) -> tuple[tuple[str, ...], list, list[str]]:
    path, rest = resolve(prog, argv)
    options, arguments = signature(prog, path)
    used, positional = split_args(options, rest, where, fenced)
    if fenced and not any(is_placeholder(t) for t in rest):
        n_min = sum(1 for _, _, req in arguments if req)
        variadic = any(v for _, v, _ in arguments)
        assert len(positional) >= n_min, f"{where}: {len(positional)} arguments, the command needs {n_min}"
        assert variadic or len(positional) <= len(arguments), \
            f"{where}: {len(positional)} arguments, the command takes {len(arguments)}"
    return path, used, positional


def make_targets(makefile: Path) -> set[str]:
    targets = set()
    for ln in makefile.read_text().splitlines():
        m = re.match(r"^([\w./%$()-][\w./%$() -]*?)\s*:(?!=)", ln)
        if m and not ln.startswith("\t"):
            targets.update(m.group(1).split())
    return targets


def check_make(argv: list[str], where: str) -> None:
    makefile, targets, i = ROOT / "Makefile", [], 1
    while i < len(argv):
        a = argv[i]
        if a == "-f":
            makefile = ROOT / argv[i + 1]
            i += 1
        elif a.startswith("-") or "=" in a:
            pass
        else:
            targets.append(a)
        i += 1
    assert makefile.is_file(), f"{where}: no {makefile.relative_to(ROOT)}"
    known = make_targets(makefile)
    for t in targets:
        assert t in known, f"{where}: {makefile.relative_to(ROOT)} has no target '{t}'"


def check_benchmark(argv: list[str], where: str) -> None:
    script = ROOT / argv[1]
    assert script.is_file(), f"{where}: no {argv[1]}"
    source = script.read_text()
    for a in argv[2:]:
        if a.startswith("--"):
            assert f'"{a.split("=")[0]}"' in source, f"{where}: {argv[1]} has no option {a}"


@pytest.mark.parametrize("page,line,argv,fenced", COMMANDS, ids=[f"{c[0]}:{' '.join(c[2])[:60]}" for c in COMMANDS])
def test_shown_command_parses(page, line, argv, fenced):
    where = f"{page}: `{line}`"
    prog = Path(argv[0]).name
    if prog in ("vcprep", "vctrain"):
        check_cli(prog, argv[1:], fenced, where)
    elif prog == "make" and fenced:
        check_make(argv, where)
    elif prog.startswith("python") and len(argv) > 1 and argv[1].startswith("benchmarks/"):
        check_benchmark(argv, where)


def test_docs_show_commands():
    """The scan finds the commands (a broken scanner would pass every check above vacuously)."""
    progs = {Path(a[0]).name for _, _, a, _ in COMMANDS}
    assert {"vcprep", "vctrain", "make"} <= progs
    assert sum(1 for c in COMMANDS if c[3]) > 50



def unquoted_semicolons(line: str) -> list[int]:
    """Positions of every ``;`` the shell would take as the end of a command inside a word (a
    character other than a blank on both sides), outside quotes and not escaped: ``--label-format
    values:road=1;ignore=255`` runs the command with ``values:road=1`` and sets a variable."""
    found, quote, i = [], None, 0
    while i < len(line):
        c = line[i]
        if quote:
            if c == "\\" and quote == '"':
                i += 1
            elif c == quote:
                quote = None
        elif c == "\\":
            i += 1
        elif c in "'\"":
            quote = c
        elif c == "#" and (i == 0 or line[i - 1].isspace()):
            break
        elif c == ";" and 0 < i < len(line) - 1 and not line[i - 1].isspace() and not line[i + 1].isspace():
            found.append(i)
        i += 1
    return found


def test_the_semicolon_finder_against_known_lines():
    line = "vcprep warp --label-format values:road=1;ignore=255 --out s"
    assert unquoted_semicolons(line) == [line.index(";")]
    assert unquoted_semicolons("vcprep warp --label-format 'values:road=1;ignore=255' --out s") == []
    assert unquoted_semicolons('vcprep warp -f "values:road=1;max=4"') == []
    assert unquoted_semicolons("vcprep warp -f values:road=1\\;max=4") == []
    assert unquoted_semicolons("cd out; ls") == [] and unquoted_semicolons("ls  # a;b") == []


def _help_examples() -> list[tuple[str, str]]:
    """(command, line) of every line of every command's help text, options' help included."""
    import typer.main

    from vcprep.cli import app as vcprep_app
    from vctrain.cli import app as vctrain_app

    out = []

    def walk(name: str, cmd) -> None:
        texts = [cmd.help or ""] + [getattr(p, "help", None) or "" for p in cmd.params]
        out.extend((name, ln.strip()) for t in texts for ln in t.splitlines() if ln.strip())
        for sub, c in getattr(cmd, "commands", {}).items():
            walk(f"{name} {sub}", c)

    walk("vcprep", typer.main.get_command(vcprep_app))
    walk("vctrain", typer.main.get_command(vctrain_app))
    return out


def test_no_command_shown_has_an_unquoted_semicolon():
    """A command pasted from the README, the docs, an Example of --help or a label-format hint runs
    as shown: every ``values:road=...;ignore=...`` is quoted."""
    lines = [(page, line) for page, line, _, _ in COMMANDS]
    lines += [(page.name, span) for page in PAGES
              for span in re.findall(r"`([^`\n]*;[^`\n]*)`", re.sub(r"^```.*?^```", "", page.read_text(), flags=re.S | re.M))
              if "values:" in span]
    lines += _help_examples()
    assert len(lines) > 200
    bad = sorted({f"{where}: {line}" for where, line in lines if unquoted_semicolons(line)})
    assert bad == []

def runnable(prog: str, path: tuple[str, ...], used, positional, cwd: Path) -> bool:
    if (prog, path) not in RUNNABLE:
        return False
    inputs = positional + [v for name, v in used if v is not None and name not in OUTPUT_OPTIONS]
    for t in inputs:
        if is_placeholder(t):
            return False
        if "*" in t:
            if not glob.glob(str(cwd / t)):
                return False
        elif ("/" in t or Path(t).suffix.lower() in PATH_SUFFIXES) and not (cwd / t).exists():
            return False
    return True


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_cheap_commands_run_on_the_examples(page, tmp_path):
    """Each page's runnable fenced commands, in order, in a folder holding examples/ (a link)."""
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    ran = 0
    for name, line, argv, fenced in COMMANDS:
        prog = Path(argv[0]).name
        if name != page.name or not fenced or prog not in ("vcprep", "vctrain"):
            continue
        path, used, positional = check_cli(prog, argv[1:], True, f"{name}: `{line}`")
        if not runnable(prog, path, used, positional, tmp_path):
            continue
        args = []
        for a in argv[1:]:
            args += sorted(os.path.relpath(p, tmp_path) for p in glob.glob(str(tmp_path / a))) if "*" in a else [a]
        proc = subprocess.run([str(BIN / prog), *args], cwd=tmp_path, capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, f"{name}: `{line}` failed:\n{proc.stderr[-2000:]}"
        ran += 1
    if page.name == "README.md":
        assert ran >= 5  # the quick start on the shipped examples


# ---------------------------------------------------------------- links


def anchors(page: Path) -> set[str]:
    """GitHub's heading anchors: lower case, punctuation but - and _ dropped, spaces to -, repeats -1, -2."""
    text = re.sub(r"^```.*?^```", "", page.read_text(), flags=re.S | re.M)
    seen: dict[str, int] = {}
    out = set()
    for title in re.findall(r"^#{1,6}\s+(.*?)\s*#*\s*$", text, re.M):
        a = re.sub(r"[^\w\- ]", "", title.strip().lower()).replace(" ", "-")
        n = seen.get(a, 0)
        seen[a] = n + 1
        out.add(a if n == 0 else f"{a}-{n}")
    return out


LINKS = [(page, target) for page in PAGES
         for target in re.findall(r"\[[^\]]*\]\(([^)\s]+)\)",
                                  re.sub(r"^```.*?^```", "", page.read_text(), flags=re.S | re.M))
         if not re.match(r"[a-z]+:", target)]


@pytest.mark.parametrize("page,target", LINKS, ids=[f"{p.name}->{t}" for p, t in LINKS])
def test_link_resolves(page, target):
    file, _, anchor = target.partition("#")
    dest = (page.parent / file).resolve() if file else page
    assert dest.exists(), f"{page.name}: link to {target}: no such file"
    assert ROOT in dest.parents or dest == ROOT, f"{page.name}: link to {target} leaves the repository"
    if anchor and dest.suffix == ".md":
        assert anchor in anchors(dest), f"{page.name}: link to {target}: no heading with that anchor"


def test_docs_have_links_and_readme_is_short():
    assert len(LINKS) > 20
    assert (ROOT / "README.md").stat().st_size <= 15_000
    readme = (ROOT / "README.md").read_text().splitlines()
    assert readme[3].startswith("make demo") and readme[4].startswith("make test")


def test_the_shipped_models_leave_one_out_table_is_the_results_files():
    """Issue 82: docs/training.md and the road-street card show ship_loo.py's table as its results file has it
    (ship_loo.embed writes it between the markers)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("ship_loo", ROOT / "benchmarks" / "other_cameras" / "ship_loo.py")
    loo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(loo)
    table = loo.table_lines((ROOT / "benchmarks" / "other_cameras" / "results" / "ship_loo.md").read_text())
    assert "| `four` |" in table and "| `today` |" in table
    for doc in loo.DOCS:
        text = doc.read_text()
        block = text[text.index("\n", text.index(loo.BEGIN)) + 1:text.index(loo.END)]
        assert block == table, doc
