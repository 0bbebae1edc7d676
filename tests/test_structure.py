"""The package's layout rules (docs/how-it-works.md, "The code"): imports run
downward (engine < project < export < cli, app), no module imports another
module's private (underscore) name, the project package loads without GL or
imgui, and no source file or class grows past what a reader can hold."""
from __future__ import annotations

import ast
import os

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGE = os.path.join(ROOT, "infinitex")
LAYERS = {"engine": 0, "project": 1, "export": 2, "cli": 3, "app": 3}
MAX_FILE_LINES = 600
MAX_CLASS_LINES = 400
MAX_ENGINE_FUNCTION_LINES = 80


def _modules():
    for folder, _, files in os.walk(PACKAGE):
        for name in sorted(files):
            if name.endswith(".py"):
                path = os.path.join(folder, name)
                rel = os.path.relpath(path, ROOT)[:-3].split(os.sep)
                if rel[-1] == "__init__":
                    rel = rel[:-1]
                yield path, ".".join(rel), name == "__init__.py"


def _imports(path: str, module: str, is_package: bool):
    """(line, imported module, [names]) of every ``from`` import and ``import``."""
    tree = ast.parse(open(path, encoding="utf-8").read())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".")
                if not is_package:
                    base = base[:-1]
                base = base[:len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            yield node.lineno, target, [a.name for a in node.names]
        elif isinstance(node, ast.Import):
            for a in node.names:
                yield node.lineno, a.name, []


def _layer(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[0] == "infinitex" and parts[1] in LAYERS else None


def test_the_layout_rules_see_every_module():
    found = {m for _, m, _ in _modules()}
    for layer in LAYERS:
        assert f"infinitex.{layer}" in found, f"infinitex/{layer}/ is missing"
    assert len(found) > 40


def test_imports_run_downward_and_take_no_private_names():
    bad = []
    for path, module, is_package in _modules():
        layer = _layer(module)
        for line, target, names in _imports(path, module, is_package):
            if not target.startswith("infinitex"):
                continue
            other = _layer(target)
            where = f"{os.path.relpath(path, ROOT)}:{line}"
            if layer and other and other != layer and LAYERS[other] >= LAYERS[layer]:
                bad.append(f"{where}: {layer} imports {target} (not below it)")
            if target != module:
                bad += [f"{where}: imports the private name {target}.{n}" for n in names
                        if n.startswith("_") and not n.startswith("__")]
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("rule", ["files", "classes"])
def test_no_source_file_or_class_too_long(rule):
    long = []
    for path, _, _ in _modules():
        src = open(path, encoding="utf-8").read()
        rel = os.path.relpath(path, ROOT)
        if rule == "files" and src.count("\n") > MAX_FILE_LINES:
            long.append(f"{rel}: {src.count(chr(10))} lines")
        if rule == "classes":
            for node in ast.walk(ast.parse(src)):
                if isinstance(node, ast.ClassDef) and node.end_lineno - node.lineno + 1 > MAX_CLASS_LINES:
                    long.append(f"{rel}: class {node.name}, {node.end_lineno - node.lineno + 1} lines")
    assert not long, "\n".join(long)


def test_no_engine_function_too_long():
    """An engine function a reader can hold: at most 80 lines (a longer one is
    parts that want names of their own)."""
    long = []
    for path, module, _ in _modules():
        if _layer(module) == "engine":
            for node in ast.walk(ast.parse(open(path, encoding="utf-8").read())):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) \
                        and node.end_lineno - node.lineno + 1 > MAX_ENGINE_FUNCTION_LINES:
                    long.append(f"{os.path.relpath(path, ROOT)}: {node.name}, {node.end_lineno - node.lineno + 1} lines")
    assert not long, "\n".join(long)


def test_the_checks_catch_what_they_look_for(tmp_path):
    """The import reader resolves relative imports as Python does (a rule
    that misread them would pass everything)."""
    p = tmp_path / "m.py"
    p.write_text("from ..export.window import ExportJob\nfrom .fields import _u16\nimport infinitex.app.session\n")
    got = list(_imports(str(p), "infinitex.engine.controls.m", False))
    assert got == [(1, "infinitex.engine.export.window", ["ExportJob"]), (2, "infinitex.engine.controls.fields", ["_u16"]),
                   (3, "infinitex.app.session", [])]
    got = list(_imports(str(p), "infinitex.project", True))
    assert got[0][1] == "infinitex.export.window" and _layer(got[0][1]) == "export"


TOOLS = os.path.join(PACKAGE, "app", "ui", "tools")


def _tool_names() -> set[str]:
    names = set()
    for path in os.listdir(TOOLS):
        if path.endswith(".py"):
            for node in ast.walk(ast.parse(open(os.path.join(TOOLS, path), encoding="utf-8").read())):
                if isinstance(node, ast.ClassDef):
                    for st in node.body:
                        if (isinstance(st, ast.Assign) and [getattr(t, "id", None) for t in st.targets] == ["name"]
                                and isinstance(st.value, ast.Constant)):
                            names.add(st.value.value)
    return names


def _is_name(node) -> bool:
    return (isinstance(node, ast.Attribute) and node.attr == "name") or (isinstance(node, ast.Name)
                                                                        and node.id == "name")


def _name_comparisons(src: str, names: set[str]) -> list[int]:
    """Lines comparing a ``name`` (``x.name``, ``name``) with a tool's name (==, !=, in, startswith)."""
    lines = []
    for node in ast.walk(ast.parse(src)):
        consts = []
        if isinstance(node, ast.Compare) and any(_is_name(c) for c in node.comparators + [node.left]):
            for c in node.comparators + [node.left]:
                consts += [c] if isinstance(c, ast.Constant) else list(getattr(c, "elts", []))
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
              and node.func.attr == "startswith" and node.args and _is_name(node.func.value)):
            consts = [node.args[0]]
        if any(isinstance(c, ast.Constant) and isinstance(c.value, str)
               and (c.value in names or any(n.startswith(c.value) for n in names if len(c.value) > 3))
               for c in consts):
            lines.append(node.lineno)
    return lines


def test_no_tool_name_is_compared_outside_the_tools():
    """A tool declares what the editor needs (app/ui/tools/__init__.py Tool);
    the editor, its panels and its model view never branch on a tool's name."""
    names = _tool_names()
    assert {"navigate", "paint-canvas", "feature", "direction", "labels", "lattice"} <= names
    bad = []
    for path, _, _ in _modules():
        if os.sep + "app" + os.sep not in path or path.startswith(TOOLS):
            continue
        bad += [f"{os.path.relpath(path, ROOT)}:{n}" for n in _name_comparisons(open(path, encoding="utf-8").read(), names)]
    assert not bad, "\n".join(bad)
    assert _name_comparisons('if ed.tool.name in ("labels", "x"): pass\nif t.name.startswith("paint"): pass\n'
                             'if tool.name == "feature": pass\nkinds = ("labels", 1)\nif ex.fit == "lattice": pass\n',
                             names) == [1, 2, 3]


def test_tool_keys_are_unique_and_free():
    """Each tool's shortcut letter is its own, and none is one of the editor's
    single keys (H fields, T tile mode, M next map: shortcuts.py)."""
    from infinitex.app.ui.tools import Tool
    from infinitex.app.ui.tools import direction, feature, labels, lattice, navigate, paint  # noqa: F401

    def subclasses(c):
        for s in c.__subclasses__():
            yield s
            yield from subclasses(s)
    keys = [c.key.upper() for c in set(subclasses(Tool)) if c.key]
    assert len(keys) >= 7 and len(keys) == len(set(keys)), sorted(keys)
    assert not set(keys) & {"H", "T", "M"}


def _graph(root: str, prefix: str) -> dict[str, set[str]]:
    """Module -> the modules under ``prefix`` it imports (at the top or inside a
    function: a lazy import is a dependency too), from the files under ``root``."""
    mods = {}
    for folder, _, files in os.walk(root):
        for name in sorted(files):
            if name.endswith(".py"):
                path = os.path.join(folder, name)
                rel = os.path.relpath(path, ROOT)[:-3].split(os.sep)
                is_package = rel[-1] == "__init__"
                mods[".".join(rel[:-1] if is_package else rel)] = (path, is_package)
    graph = {}
    for module, (path, is_package) in mods.items():
        out = set()
        for _, target, names in _imports(path, module, is_package):
            for t in [target] + [f"{target}.{n}" for n in names]:
                if t in mods and t != module and t.startswith(prefix):
                    out.add(t)
        graph[module] = out
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_subpackages_depend_one_way():
    """No import cycle inside the engine (engine/surface included), none between
    engine/controls and engine/surface (the controls know a model's atlas only
    as an object with methods), app/render never imports app/ui (drawing knows
    no panel or tool), and the benchmarks never import the scripts."""
    engine = _graph(os.path.join(PACKAGE, "engine"), "infinitex.engine")
    assert _cycles(engine) == []
    assert not [(m, t) for m, ts in engine.items() for t in ts
                if m.startswith("infinitex.engine.controls") and t.startswith("infinitex.engine.surface")]
    app = _graph(os.path.join(PACKAGE, "app"), "infinitex.app")
    assert not [(m, t) for m, ts in app.items() for t in ts
                if m.startswith("infinitex.app.render") and t.startswith("infinitex.app.ui")]
    for folder, _, files in os.walk(os.path.join(ROOT, "bench")):
        for name in files:
            if name.endswith(".py"):
                path = os.path.join(folder, name)
                bad = [t for _, t, _ in _imports(path, "bench." + name[:-3], False) if t.split(".")[0] == "scripts"]
                assert not bad, f"{os.path.relpath(path, ROOT)} imports {bad}"
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def _programs_built_apart(src: str) -> list[int]:
    """Lines that compile GL programs themselves (``.program(vertex_shader=...)``)
    or carry GLSL in a Python string (a ``#version`` line)."""
    out = []
    for node in ast.walk(ast.parse(src)):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "program"
                and any(k.arg in ("vertex_shader", "fragment_shader") for k in node.keywords)):
            out.append(node.lineno)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and "#version" in node.value:
            out.append(node.lineno)
    return sorted(set(out))


def test_every_shader_comes_from_files_through_one_loader():
    """The engine, the canvas and the model view build their programs with
    engine/gpu.py's build_program, from GLSL files: no GLSL in Python strings,
    no program compiled elsewhere."""
    loader = os.path.join(PACKAGE, "engine", "gpu.py")
    bad = []
    for path, _, _ in _modules():
        lines = _programs_built_apart(open(path, encoding="utf-8").read())
        if path == loader:
            assert len(lines) == 2, lines  # the one ctx.program call, GLSL_VERSION
            continue
        bad += [f"{os.path.relpath(path, ROOT)}:{n}" for n in lines]
    assert not bad, "\n".join(bad)
    assert _programs_built_apart('p = ctx.program(vertex_shader=V, fragment_shader=F)\n'
                                 'VERT = """\n#version 330 core\nvoid main() {}\n"""\nq = gpu.program("copy.frag")\n') == [1, 2]


# The editor's parts: Editor.<attribute> -> (the module defining the part, its class).
EDITOR_PARTS = {"files": ("files.py", "Documents"), "exports": ("exports.py", "Exports"),
                "canvas_input": ("canvas_input.py", "CanvasInput"), "refinement": ("canvas_refine.py", "CanvasRefine"),
                "shortcuts": ("shortcuts.py", "Shortcuts"), "model": ("model_mode.py", "ModelMode"),
                "tools": (os.path.join("tools", "__init__.py"), "Tools")}


def _editor_writes(src: str, own: tuple[str, str] | None) -> set[str]:
    """The editor's state a module assigns, not counting first values
    (``__init__``): ``x`` for the Editor's attribute (``ed.x``, ``self.ed.x``
    anywhere; ``self.x`` in the class Editor), ``part.x`` for a part's
    (``ed.part.x``, ``self.ed.part.x`` anywhere, ``self.part.x`` in the class
    Editor; ``self.x`` in the part's own class). ``own``: (part, class) when the
    module defines the Editor (part "") or a part."""
    out = set()
    tree = ast.parse(src)
    skip, mine = set(), set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef) and own is not None and node.name == own[1]:
            mine |= {id(n) for n in ast.walk(node)}
            for f in node.body:
                if isinstance(f, ast.FunctionDef) and f.name == "__init__":
                    skip |= {id(n) for n in ast.walk(f)}

    def editor(v) -> bool:  # ed, editor, self.ed; self in the Editor itself
        return (isinstance(v, ast.Name) and (v.id in ("ed", "editor") or (v.id == "self" and own is not None
                                                                          and own[0] == "" and id(v) in mine))) \
            or (isinstance(v, ast.Attribute) and v.attr == "ed" and isinstance(v.value, ast.Name))
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] \
            if isinstance(node, (ast.AugAssign, ast.AnnAssign)) else []
        for t in targets:
            for x in (t.elts if isinstance(t, (ast.Tuple, ast.List)) else [t]):
                if not isinstance(x, ast.Attribute):
                    continue
                v = x.value
                if editor(v):
                    out.add(x.attr)
                elif isinstance(v, ast.Attribute) and v.attr in EDITOR_PARTS and editor(v.value):
                    out.add(f"{v.attr}.{x.attr}")
                elif isinstance(v, ast.Name) and v.id == "self" and own is not None and own[0] and id(v) in mine:
                    out.add(f"{own[0]}.{x.attr}")
    return out


def test_editor_state_has_one_writer():
    """Each piece of the editor's state is written from one module (its owner:
    Viewer for the view and the display, CanvasState for what the canvas did,
    Preferences for the user's settings, the Export panel for ExportSettings,
    each of the editor's parts for its own state...)."""
    base = os.path.join(PACKAGE, "app", "ui")
    owner = {os.path.join(base, m): (part, cls) for part, (m, cls) in EDITOR_PARTS.items()}
    owner[os.path.join(base, "editor.py")] = ("", "Editor")
    writers: dict[str, set[str]] = {}
    for folder, _, files in os.walk(base):
        for name in files:
            if name.endswith(".py"):
                path = os.path.join(folder, name)
                for attr in _editor_writes(open(path, encoding="utf-8").read(), owner.get(path)):
                    writers.setdefault(attr, set()).add(os.path.relpath(path, base))
    shared = {a: sorted(w) for a, w in writers.items() if len(w) > 1}
    assert not shared, shared
    assert _editor_writes("def f(ed):\n    ed.view = 1\n    ed.a.b = 2\n    _, ed.c = 1, 2\n    self.ed.d = 3\n"
                          "    ed.files.e = 4\n    self.ed.model.f = 5\n    self.g = 6\n    ed.tools.active = 7\n",
                          None) == {"view", "c", "d", "files.e", "model.f", "tools.active"}
    part = "class Model:\n    def __init__(self):\n        self.a = 1\n    def f(self):\n        self.b = 2\n" \
           "class Other:\n    def f(self):\n        self.c = 3\n"
    assert _editor_writes(part, ("model", "Model")) == {"model.b"}
    editor = "class Editor:\n    def __init__(self):\n        self.a = 1\n    def f(self):\n        self.b = 2\n" \
             "        self.files.pending = 3\n        self.viewer.x = 4\n"
    assert _editor_writes(editor, ("", "Editor")) == {"b", "files.pending"}


def test_the_editor_is_composed_not_mixed_in():
    """No class of the package has two or more bases defined in the package
    (the editor's and the pyramid's parts are collaborators with their own
    state, not mixins sharing one ``self``)."""
    classes = {}
    for path, _, _ in _modules():
        for node in ast.walk(ast.parse(open(path, encoding="utf-8").read())):
            if isinstance(node, ast.ClassDef):
                classes.setdefault(node.name, []).append((os.path.relpath(path, ROOT), node))
    mixed = [f"{rel}: class {node.name}" for found in classes.values() for rel, node in found
             if sum(isinstance(b, ast.Name) and b.id in classes for b in node.bases) > 1]
    assert not mixed, "\n".join(mixed)


def test_the_fast_sets_long_tests_exist():
    """Every test tests/fast_set.py leaves out of the fast set is still a test
    function of its file (a renamed test would silently come back into it)."""
    from fast_set import LONG
    for nodeid in LONG:
        path, _, name = nodeid.partition("::")
        with open(os.path.join(ROOT, path), encoding="utf-8") as f:
            tree = ast.parse(f.read())
        names = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
        assert name.split("[")[0] in names, nodeid
