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
