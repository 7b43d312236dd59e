"""The house rules, read from the source: who may import whom, one command table, no stray packages.

- ``lasercal.solver`` is the core: it imports neither ``vision`` nor ``collector`` (nor the front door),
  and never prints.
- ``lasercal.vision`` stands alone (no ``solver``, no ``collector``).
- ``lasercal.collector`` is the application, the only room that imports the others; argparse lives only
  in its ``cli`` package.
- ``lasercal`` itself (the folder ``collector/api``) is the application's front door, the workflow as
  Python: it may use ``collector.report`` (the report, the printed summary) and ``vision`` (spots), only
  inside its functions (``import lasercal`` loads nothing), and never ``collector.cli``; nothing in
  ``solver`` or ``vision`` imports it. :func:`picture` draws which room imports which.
- the solver's floors: ``kinematics`` < ``formats`` < ``identify``, ``control`` < ``analysis``; a module
  imports its own floor and those below (``formats`` never takes a name from ``identify``: the one
  exception is listed in :data:`UPWARD`).
- no file-level import circles anywhere, lazy (function-level) and annotation-only imports included: two
  files that need each other share a name that belongs in a third, or in one of them.
- every command in the table imports and declares its arguments and handler.
- no function is longer than a page: at most :data:`MAX_FUNCTION_LINES` lines from its ``def`` to its last
  line, docstring included.
- the simulated worlds live in one room, ``collector.worlds``: everything else reaches a world only through
  the backend factory (``collector.hardware``; the demo, which stages its own bench, is the one listed
  exception, :data:`WORLD_GATES`); a world imports no session, command line, view or report; parsing a
  command imports no world.
"""

from __future__ import annotations

import argparse
import ast
import re
import subprocess
import sys
import tomllib
from pathlib import Path

from lasercal.collector.cli.main import COMMANDS, build_parser, load

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {"solver": ROOT / "solver", "vision": ROOT / "vision", "collector": ROOT / "collector"}
API = ROOT / "collector" / "api"  # the package ``lasercal`` itself, the front door (pyproject's package-dir)
# the rooms: the three packages and the front door ('api', the package ``lasercal`` itself)
ROOMS = (*PACKAGES, "api")
# who may import whom: only the application (with its front door) imports the other rooms
MAY_IMPORT = {
    "solver": set(),
    "vision": set(),
    "collector": {"solver", "vision", "api"},
    "api": {"solver", "vision", "collector"},
}
# the solver's floors (lasercal.solver.<floor>); a module imports its own floor and the ones below
FLOORS = {"errors": 0, "kinematics": 1, "formats": 2, "identify": 3, "control": 3, "analysis": 4}
# the known upward import: a full-pose file's reader computes each pose from its circle points (Section 2.3)
UPWARD = {("lasercal.solver.formats.fullpose_io", "lasercal.solver.identify.circlepoint")}
# what the top floor may reach of the application, inside its functions
# the front door's functions may reach the reports, vision, what a camera session's coach plans with, and the
# simulated world through the backend factory (``simulate`` draws the arm's joints there)
API_REACHES = (
    "lasercal.collector.report",
    "lasercal.vision",
    "lasercal.collector.sessions.anywhere",
    "lasercal.collector.hardware",
)


# the only modules outside collector.worlds that import a world: the backend factory, and the demo (a bench it
# stages itself: a robot with one hidden effect, a camera that ticks the robot's clock)
WORLD_GATES = {"lasercal.collector.hardware", "lasercal.collector.demo"}
WORLDS = "lasercal.collector.worlds"
# what a world may import of the application: the hardware interfaces and its errors, nothing that runs a
# session
WORLD_REACHES = ("lasercal.collector.hardware", "lasercal.collector.errors", WORLDS)

# a function's longest: its ``def`` line to its last line, docstring included
MAX_FUNCTION_LINES = 100


def module_name(f: Path) -> str:
    """The dotted name of a source file (``collector/api/x.py`` is ``lasercal.x``)."""
    if f.is_relative_to(API):
        parts = ("lasercal",) + f.relative_to(API).with_suffix("").parts
    else:
        parts = ("lasercal",) + f.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules(pkg: str) -> dict[str, Path]:
    """Dotted module name -> file, for every module of ``lasercal.<pkg>`` ('api': of ``lasercal`` itself;
    'collector' leaves the api out)."""
    if pkg == "api":
        return {module_name(f): f for f in sorted(API.rglob("*.py"))}
    files = [f for f in sorted(PACKAGES[pkg].rglob("*.py")) if not f.is_relative_to(API)]
    return {module_name(f): f for f in files}


def every_module() -> dict[str, Path]:
    return {k: v for pkg in ROOMS for k, v in modules(pkg).items()}


def room(module: str) -> str:
    """The room of a dotted module name: 'solver', 'vision', 'collector' or 'api' (the front door)."""
    part = module.split(".")[1] if "." in module else None
    return part if part in PACKAGES else "api"


def room_imports(files: dict[str, list[Path]] | None = None) -> dict[str, set[str]]:
    """Room -> the other rooms its files import (lazy and annotation-only imports included); ``files``:
    room -> its source files (default: the repository's)."""
    files = files or {r: list(modules(r).values()) for r in ROOMS}
    found = {r: set() for r in files}
    for r, paths in files.items():
        for f in paths:
            found[r].update(room(m) for m in imports(f) if m != "lasercal" and room(m) != r)
    return found


def picture() -> str:
    """Which room imports which, one line a room, drawn from the source."""
    names = {
        "api": "lasercal (collector/api, the front door)",
        "collector": "lasercal.collector",
        "solver": "lasercal.solver",
        "vision": "lasercal.vision",
    }
    graph = room_imports()
    return "\n".join(
        f"{names[r]:41s} -> {', '.join(names[t].split(' ')[0] for t in sorted(graph[r])) or '(nothing)'}"
        for r in ("api", "collector", "solver", "vision")
    )


def imports(path: Path, top_level_only: bool = False) -> set[str]:
    """The lasercal modules a file imports (absolute imports; the project uses no relative ones), lazy and
    annotation-only imports included unless ``top_level_only``. ``from lasercal.x import y`` names the
    module ``lasercal.x.y`` when y is a module."""
    known = every_module()
    tree = ast.parse(path.read_text())
    nodes = tree.body if top_level_only else ast.walk(tree)
    found = set()
    for node in nodes:
        if isinstance(node, ast.ImportFrom):
            assert node.level == 0, f"{path}: relative import"
            if node.module and node.module.startswith("lasercal"):
                found.add(node.module)
                found.update(
                    f"{node.module}.{a.name}" for a in node.names if f"{node.module}.{a.name}" in known
                )
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("lasercal"))
    return found


def import_graph() -> dict[str, set[str]]:
    """Module -> the modules of the project it imports (a package's ``__init__`` not counted as a step)."""
    mods = every_module()
    return {m: {i for i in imports(f) if i in mods and i != m and i != "lasercal"} for m, f in mods.items()}


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import circles: strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while not comp or comp[-1] != v:
                comp.append(stack.pop())
                on.discard(comp[-1])
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_only_the_application_imports_the_other_rooms():
    """solver and vision import no other room; the application and its front door import the rest. The
    picture is asserted whole, so that a new arrow between rooms is a decision, not an accident."""
    graph = room_imports()
    assert all(graph[r] <= MAY_IMPORT[r] for r in ROOMS), graph
    print(picture())
    assert picture().splitlines() == [
        "lasercal (collector/api, the front door)  -> lasercal.collector, lasercal.solver, lasercal.vision",
        "lasercal.collector                        -> lasercal, lasercal.solver, lasercal.vision",
        "lasercal.solver                           -> (nothing)",
        "lasercal.vision                           -> (nothing)",
    ]
    assert picture() in (ROOT / "docs" / "api.md").read_text()  # the picture docs/api.md shows


def test_an_arrow_from_the_bottom_floor_up_is_seen(tmp_path):
    """A solver file importing the report (lazily) or the front door is an arrow the picture shows."""
    up = tmp_path / "up.py"
    up.write_text("def f():\n    from lasercal.collector.report.text import format_solve\n")
    door = tmp_path / "door.py"
    door.write_text("from lasercal.calibration import calibrate\n")
    assert room_imports({"solver": [up, door]})["solver"] == {"collector", "api"}


def test_only_the_command_line_imports_the_command_line():
    for pkg in ROOMS:
        for name, f in modules(pkg).items():
            if not name.startswith("lasercal.collector.cli"):
                assert not [m for m in imports(f) if m.startswith("lasercal.collector.cli")], name


def world_arrows() -> tuple[list, list]:
    """(modules outside the worlds' room that import a world, other than :data:`WORLD_GATES`; a world's
    imports of the application outside :data:`WORLD_REACHES`), as (importer, imported) pairs."""
    into, out = [], []
    for name, f in every_module().items():
        inside = name == WORLDS or name.startswith(WORLDS + ".")
        for m in imports(f):
            if not inside and m.startswith(WORLDS) and name not in WORLD_GATES:
                into.append((name, m))
            if (
                inside
                and (m.startswith("lasercal.collector") or room(m) == "api")
                and not m.startswith(WORLD_REACHES)
            ):
                out.append((name, m))
    return into, out


def test_the_worlds_are_reached_only_through_the_backend_factory():
    into, out = world_arrows()
    assert into == [], into
    assert out == [], out
    factory = ROOT / "collector" / "hardware" / "__init__.py"
    assert any(m.startswith(WORLDS) for m in imports(factory))  # the gate is used, not a dead rule
    assert not any(m.startswith(WORLDS) for m in imports(factory, top_level_only=True))  # and lazily


def test_a_session_importing_a_world_breaks_the_rule(monkeypatch, tmp_path):
    """The rule sees a session that imports a world directly, lazily, by its own name."""
    rogue = ROOT / "collector" / "sessions" / "capture.py"
    rogue_import = "\n\ndef _rogue():\n    from lasercal.collector.worlds.fake import FakeRobot\n"
    text = rogue.read_text() + rogue_import
    real = Path.read_text
    monkeypatch.setattr(
        Path, "read_text", lambda self, *a, **k: text if self == rogue else real(self, *a, **k)
    )
    into, _ = world_arrows()
    assert ("lasercal.collector.sessions.capture", "lasercal.collector.worlds.fake") in into


def test_parsing_a_command_imports_no_world(tmp_path):
    """The capture command's options (a fake backend, its effects) are parsed and turned into a session's
    settings without loading a world: the names live in collector.hardware.simulated."""
    layout = ROOT / "data" / "layouts" / "thesis.yaml"
    code = (
        "import sys\n"
        "from lasercal.collector.cli.main import build_parser\n"
        "from lasercal.collector.sessions.settings import capture_settings\n"
        "args = ['capture', '--backend', 'fake', '--effects', 'paper-curl,print-shear', '--robot', 'panda']\n"
        f"args += ['--per-point', '2', '--layout', {str(layout)!r}, '-o', {str(tmp_path / 's')!r}]\n"
        "a = build_parser('capture').parse_args(args)\n"
        "s = capture_settings({'backend': 'fake', 'effects': a.effects, 'robot': 'panda', 'per_point': 2},\n"
        "                     a.layout, a.output)\n"
        "print(s.cfg['effects'])\n"
        "print(sorted(m for m in sys.modules if m.startswith('lasercal.collector.worlds')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines() == ["['paper-curl', 'print-shear']", "[]"], out.stdout


def long_functions(source: str, limit: int = MAX_FUNCTION_LINES) -> list[tuple[str, int]]:
    """The functions (methods and nested ones too) of a source longer than ``limit`` lines.

    Parameters
    ----------
    source : str
        A Python module's text.
    limit : int
        The most lines a function may have, its ``def`` line to its last line.

    Returns
    -------
    list of (str, int)
        Each too-long function's name and length, in the order they stand.
    """
    return [
        (node.name, node.end_lineno - node.lineno + 1)
        for node in ast.walk(ast.parse(source))
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
        and node.end_lineno - node.lineno + 1 > limit
    ]


def every_long_function() -> dict[tuple[str, str], int]:
    """(file relative to the repository, function) -> lines, for every function over the limit in the three
    packages."""
    return {
        (f.relative_to(ROOT).as_posix(), name): length
        for pkg in PACKAGES.values()
        for f in sorted(pkg.rglob("*.py"))
        for name, length in long_functions(f.read_text())
    }


def test_no_function_is_longer_than_a_page():
    assert every_long_function() == {}


def test_a_function_over_a_page_is_seen():
    body = "".join(f"    x{i} = {i}\n" for i in range(MAX_FUNCTION_LINES - 1))
    page = "def page():\n" + body  # exactly the limit: allowed
    over = "class A:\n    def over(self):\n        y = 0\n" + body.replace("    ", "        ")
    assert long_functions(page) == []
    assert long_functions(page + over) == [("over", MAX_FUNCTION_LINES + 1)]


def test_solver_never_prints_nor_parses_arguments():
    for name, f in modules("solver").items():
        tree = ast.parse(f.read_text())
        calls = {
            n.func.id for n in ast.walk(tree) if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)
        }
        assert "print" not in calls, name
        assert "argparse" not in f.read_text(), name


def test_argparse_only_in_the_cli_package():
    for pkg in ROOMS:
        for name, f in modules(pkg).items():
            if not name.startswith("lasercal.collector.cli"):
                assert "import argparse" not in f.read_text(), name


def test_no_file_imports_itself_through_others():
    """No import circles, two files or more, lazy imports included (in all of lasercal)."""
    assert circles(import_graph()) == []


def test_circles_are_found():
    """The circle finder on a graph with a two-file circle, a three-file circle and a chain."""
    g = {"a": {"b"}, "b": {"a"}, "c": {"d"}, "d": {"e"}, "e": {"c"}, "f": {"a"}}
    assert sorted(circles(g)) == [["a", "b"], ["c", "d", "e"]]


def test_the_solver_imports_no_floor_above_its_own():
    up = set()
    for name, f in modules("solver").items():
        floor = name.split(".")[2] if name.count(".") >= 2 else None
        for m in imports(f):
            target = m.split(".")[2] if m.startswith("lasercal.solver.") else None
            if floor in FLOORS and target in FLOORS and FLOORS[target] > FLOORS[floor]:
                up.add((name, m))
    assert up == UPWARD


def test_the_top_floor_reaches_the_application_lazily():
    """``lasercal`` (collector/api) takes collector.report, vision, the camera coach's sheet cells
    (collector.sessions.anywhere) and the backend factory (collector.hardware) inside its functions only,
    never the command line; neither solver nor vision imports it."""
    api = modules("api")
    for name, f in api.items():
        app = {m for m in imports(f) if m.split(".")[1] in ("collector", "vision")}
        assert all(m.startswith(API_REACHES) for m in app), (name, app)
        assert not {m for m in imports(f, top_level_only=True) if m.split(".")[1] in ("collector", "vision")}
    for pkg in ("solver", "vision"):
        for name, f in modules(pkg).items():
            assert not [m for m in imports(f) if m in api and m != "lasercal"], name


def test_every_declared_command_imports_with_arguments_and_handler():
    assert len({c.name for c in COMMANDS}) == len(COMMANDS)
    for c in COMMANDS:
        mod = load(c)
        assert callable(getattr(mod, c.handler)), c
        assert callable(getattr(mod, "args_" + c.name.replace("-", "_"))), c
        sub = next(a for a in build_parser(c.name)._actions if isinstance(a, argparse._SubParsersAction))
        # the handler runs behind the one check of the command's output paths (main.outputs_checked)
        assert sub.choices[c.name].get_default("func").__wrapped__ is getattr(mod, c.handler)


def test_help_imports_no_command_module():
    code = (
        "import sys; from lasercal.collector.cli.main import main\n"
        "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
        "cli = sorted(m for m in sys.modules if m.startswith('lasercal.collector.cli'))\n"
        "print(cli, 'numpy' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == "['lasercal.collector.cli', 'lasercal.collector.cli.main'] False"


def test_pyproject_lists_every_package_and_only_lasercal():
    """Every folder with an __init__.py is listed, named through the package-dir mappings (``lasercal``
    itself is the folder collector/api: the repository keeps its top-level folders)."""
    conf = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(conf["packages"])
    folders = sorted(conf["package-dir"].items(), key=lambda kv: -len(kv[1]))  # the deepest mapping first

    def package(folder: Path) -> str:
        rel = folder.relative_to(ROOT).as_posix()
        pkg, d = next((pkg, d) for pkg, d in folders if rel == d or rel.startswith(d + "/"))
        return pkg + rel[len(d) :].replace("/", ".")

    on_disk = {"lasercal.data"} | {
        package(p.parent) for pkg in PACKAGES.values() for p in pkg.rglob("__init__.py")
    }
    assert listed == on_disk
    assert all(p.split(".")[0] == "lasercal" for p in listed)
    assert conf["package-dir"]["lasercal"] == "collector/api"


def test_import_lasercal_is_lazy():
    """``import lasercal`` (what ``lasercal --help`` does first) loads nothing; its API loads on use."""
    code = (
        "import sys, lasercal\n"
        "print(sorted(m for m in sys.modules if m.startswith('lasercal')), 'numpy' in sys.modules)\n"
        "print(lasercal.load_model.__module__, 'numpy' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.splitlines() == ["['lasercal'] False", "lasercal.solver.control.robot True"]


def test_ci_runs_the_readme_test_command():
    """.ci/run ends with the README's test command, word for word (the README says it is what CI runs)."""
    line = next(
        ln for ln in (ROOT / "README.md").read_text().splitlines() if "exactly what .ci/run runs" in ln
    )
    command = line.split("#")[0].strip()
    assert command.startswith("pip install") and " -n auto" in command  # the tests on every core
    assert (ROOT / ".ci" / "run").read_text().strip().splitlines()[-1] == command


ARCHITECTURE = ROOT / "docs" / "architecture.md"


def named_paths(text: str) -> set[str]:
    """The repository paths a page names in backticks (``collector/worlds/``, ``solver/formats/``, a file)."""
    return set(re.findall(r"`((?:collector|solver|vision|data|tests|benchmarks|docs)/[\w./]*)`", text))


def test_the_architecture_page_matches_the_tree():
    """docs/architecture.md names only paths that exist, every package of the three (a folder with an
    __init__.py) and the import picture the source draws."""
    text = ARCHITECTURE.read_text()
    paths = named_paths(text)
    assert len(paths) > 20
    assert [p for p in sorted(paths) if not (ROOT / p).exists()] == []
    packages = {
        f"{p.parent.relative_to(ROOT)}/"
        for pkg in PACKAGES.values()
        for p in pkg.rglob("__init__.py")
        if p.parent != pkg
    }
    assert sorted(packages - paths) == []
    assert picture() in text


def test_a_page_naming_a_gone_file_is_caught():
    assert named_paths("see `collector/worlds/gone.py` and `solver/identify/`") == {
        "collector/worlds/gone.py",
        "solver/identify/",
    }
    assert not (ROOT / "collector/worlds/gone.py").exists()
