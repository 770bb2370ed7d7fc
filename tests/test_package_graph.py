"""The package graph the README draws is the one the code has: nothing imports upward, and
every package declares its public modules and ships type information."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("gaide_core", "calibration", "perception", "planning", "execution", "gaide")


def readme_graph() -> dict[str, set[str]]:
    """package -> the project packages it may import, read from the README's drawing."""
    text = (ROOT / "README.md").read_text()
    block = text.split("## Package graph", 1)[1].split("```", 2)[1]
    graph: dict[str, set[str]] = {}
    for line in block.splitlines():
        m = re.match(r"^([a-z_]+)\s+(->\s+([a-z_, ]+?))?\s{2,}", line + "  ")
        if not m or m.group(1) not in PACKAGES:
            continue
        targets = m.group(3) or ""
        if targets.strip() == "everything":
            graph[m.group(1)] = set(PACKAGES) - {m.group(1)}
        else:
            graph[m.group(1)] = {t.strip() for t in targets.split(",") if t.strip()}
    return graph


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(), str(path))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module.split(".")[0])
    return names & set(PACKAGES)


def test_the_readme_draws_every_package() -> None:
    assert set(readme_graph()) == set(PACKAGES)


def test_no_package_imports_upward() -> None:
    wrong = []
    for package, allowed in readme_graph().items():
        for path in sorted((ROOT / package).rglob("*.py")):
            bad = _imports(path) - allowed - {package}
            if bad:
                wrong.append(f"{path.relative_to(ROOT)} imports {sorted(bad)}")
    assert not wrong, "\n".join(wrong)


def test_nothing_imports_the_cli_package() -> None:
    users = [
        str(path.relative_to(ROOT))
        for package in PACKAGES
        if package != "gaide"
        for path in (ROOT / package).rglob("*.py")
        if "gaide" in _imports(path)
    ]
    assert not users


def test_every_package_declares_its_modules_and_ships_types() -> None:
    wrong = []
    for package in PACKAGES:
        for init in sorted((ROOT / package).rglob("__init__.py")):
            folder = init.parent
            tree = ast.parse(init.read_text())
            declared = None
            for node in tree.body:
                if isinstance(node, ast.Assign) and any(
                    isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets
                ):
                    declared = set(ast.literal_eval(node.value))
            name = folder.relative_to(ROOT)
            if declared is None:
                wrong.append(f"{name}: no __all__")
            if ast.get_docstring(tree) is None:
                wrong.append(f"{name}: no docstring")
            if not (folder / "py.typed").exists():
                wrong.append(f"{name}: no py.typed")
            if declared is not None:
                modules = {p.stem for p in folder.glob("*.py") if not p.stem.startswith("_")} | {
                    p.name for p in folder.iterdir() if (p / "__init__.py").exists()
                }
                if declared != modules:
                    wrong.append(
                        f"{name}: __all__ {sorted(declared ^ modules)} differ from its modules"
                    )
    assert not wrong, "\n".join(wrong)
