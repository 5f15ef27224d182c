"""The structure report: the import graph of python/fakeack (and, with --rust, of rust/src).

`python tests/import_graph.py [--root PATH] [--json] [--rust]` prints the levels (level 0 imports
no other fakeack module, level k only lower levels), the edges and the cycles, and exits 1 on

- an import cycle (function-level imports count: the whole syntax tree is walked);
- a private name (`_x`, not `__x__`) imported from a module of another subpackage (the first
  component under fakeack; each top-level module is its own); names from a module with a private
  component (`fakeack._internal.*`, `fakeack._fakeack`, `detection._quadform`) are allowed;
- a library module (not under fakeack.cli nor fakeack.__main__) importing fakeack.cli;
- a Python module over 500 lines or a Rust file over 600 (test files excluded);
- with --rust, a cycle among the crate's top-level modules (`crate::X` paths).

Package `__init__` modules are modules. `from pkg import name`, when `pkg/__init__.py` only
re-exports `name` from a submodule, is an edge to that submodule, so a submodule taking a name
from its own package is not a trivial package/submodule cycle; every other cycle, through an
`__init__` or not, is reported. The Rust cycle check ignores test code: files named tests.rs, files
under a tests/ directory and inline `#[cfg(test)] mod x { ... }` blocks.
"""

from __future__ import annotations

import argparse
import ast
import json
import re
import sys
from collections.abc import Iterator
from pathlib import Path

PY_LIMIT, RS_LIMIT = 500, 600
Edges = dict[str, set[str]]
Sites = dict[tuple[str, str], list[str]]


def private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def subpackage(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def find_modules(pkg_dir: Path) -> dict[str, Path]:
    """Module name -> file; a compiled extension counts through its stub (`_fakeack.pyi`)."""
    modules: dict[str, Path] = {}
    for path in sorted(pkg_dir.rglob("*.py*")):
        if path.suffix not in (".py", ".pyi") or "__pycache__" in path.parts:
            continue
        parts = list(path.relative_to(pkg_dir.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        name = ".".join(parts)
        if path.suffix == ".py" or name not in modules:
            modules[name] = path
    return modules


def top_level(tree: ast.Module) -> Iterator[ast.ImportFrom]:
    """The from-imports that bind module-level names (not inside functions or classes)."""
    stack: list[ast.AST] = list(tree.body)
    while stack:
        node = stack.pop()
        if isinstance(node, ast.ImportFrom):
            yield node
        elif not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            stack.extend(ast.iter_child_nodes(node))


class PythonGraph:
    def __init__(self, pkg_dir: Path) -> None:
        self.root = pkg_dir.parent.parent
        self.files = find_modules(pkg_dir)
        self.trees: dict[str, ast.Module] = {}
        self.problems: list[str] = []
        for name, path in self.files.items():
            try:
                self.trees[name] = ast.parse(path.read_text(encoding="utf-8"), str(path))
            except (OSError, SyntaxError, UnicodeDecodeError) as exc:
                self.problems.append(f"{path.relative_to(self.root)}: cannot read: {exc}")
        self.edges: Edges = {name: set() for name in self.files}
        self.sites: Sites = {}
        for name, tree in self.trees.items():
            self.scan(name, tree)

    def is_package(self, name: str) -> bool:
        return self.files[name].stem == "__init__"

    def absolute(self, module: str, node: ast.ImportFrom) -> str:
        if not node.level:
            return node.module or ""
        base = module.split(".")
        base = base[: len(base) - node.level + self.is_package(module)]
        return ".".join(base + ([node.module] if node.module else []))

    def origin(self, module: str, name: str, seen: frozenset[str] = frozenset()) -> str:
        """The module defining `name` when a package `__init__` only re-exports it."""
        if module not in self.trees or module in seen or not self.is_package(module):
            return module
        for node in top_level(self.trees[module]):
            for alias in node.names:
                if (alias.asname or alias.name) == name:
                    source = self.absolute(module, node)
                    if f"{source}.{alias.name}" in self.files:
                        return f"{source}.{alias.name}"
                    if source in self.files:
                        return self.origin(source, alias.name, seen | {module})
        return module

    def add(self, src: str, dst: str, where: str) -> None:
        if dst != src and dst in self.files:
            self.edges[src].add(dst)
            if where not in self.sites.setdefault((src, dst), []):
                self.sites[src, dst].append(where)

    def scan(self, src: str, tree: ast.Module) -> None:
        in_cli = src in ("fakeack.__main__", "fakeack.cli") or src.startswith("fakeack.cli.")
        for node in ast.walk(tree):
            where = f"{self.files[src].relative_to(self.root)}:{getattr(node, 'lineno', 0)}"
            targets: list[str] = []
            if isinstance(node, ast.Import):
                for alias in node.names:
                    parts = alias.name.split(".")
                    found = [".".join(parts[:i]) for i in range(len(parts), 0, -1)]
                    targets += [next((m for m in found if m in self.files), alias.name)]
            elif isinstance(node, ast.ImportFrom):
                source = self.absolute(src, node)
                for alias in node.names:
                    sub = f"{source}.{alias.name}"
                    target = sub if sub in self.files else self.origin(source, alias.name)
                    targets.append(target)
                    checked = target if sub in self.files else source
                    if (
                        private(alias.name)
                        and source in self.files
                        and subpackage(source) != subpackage(src)
                        and not any(private(p) for p in checked.split(".")[1:])
                    ):
                        self.problems.append(f"{where}: private {alias.name} imported from {source}")
            for target in targets:
                self.add(src, target, where)
                if not in_cli and (target == "fakeack.cli" or target.startswith("fakeack.cli.")):
                    self.problems.append(f"{where}: library module {src} imports {target}")


def blank(text: str) -> str:
    return re.sub(r"[^\n]", " ", text)


def rust_strip(text: str) -> str:
    """Rust source with comments and inline `#[cfg(test)] mod x { ... }` blocks blanked (lines kept)."""
    text = re.sub(r"/\*.*?\*/|//[^\n]*", lambda m: blank(m.group(0)), text, flags=re.S)
    while match := re.search(r"#\[cfg\(test\)\]\s*(pub(\([^)]*\))?\s+)?mod\s+\w+\s*\{", text):
        depth, end = 1, match.end()
        while depth and end < len(text):
            depth += {"{": 1, "}": -1}.get(text[end], 0)
            end += 1
        text = text[: match.start()] + blank(text[match.start() : end]) + text[end:]
    return text


def crate_names(text: str) -> Iterator[tuple[int, str]]:
    """(line, first component) of every `crate::X...` path, `crate::{a, b::c}` groups included."""
    for match in re.finditer(r"(?<![\w$])crate::(\{|\w+)", text):
        line = text.count("\n", 0, match.start()) + 1
        if match.group(1) != "{":
            yield line, match.group(1)
            continue
        depth, end = 1, match.end()
        while depth and end < len(text):
            depth += {"{": 1, "}": -1}.get(text[end], 0)
            end += 1
        group = text[match.end() : end - 1]
        while re.search(r"\{[^{}]*\}", group):
            group = re.sub(r"\{[^{}]*\}", "", group)
        yield from ((line, name) for name in re.findall(r"(?:^|,)\s*(\w+)", group))


def is_test_file(path: Path, src: Path) -> bool:
    return path.name == "tests.rs" or "tests" in path.relative_to(src).parts[:-1]


class RustGraph:
    def __init__(self, src: Path) -> None:
        self.src, self.problems = src, list[str]()
        self.files = sorted(src.rglob("*.rs"))
        tops = {p.stem for p in src.glob("*.rs") if p.stem not in ("lib", "main")}
        tops |= {p.name for p in src.iterdir() if p.is_dir() and any(p.rglob("*.rs"))}
        self.edges: Edges = {top: set() for top in sorted(tops)}
        self.sites: Sites = {}
        exported: dict[str, str] = {}  # `pub use module::{Name, ...}` in lib.rs: Name -> module
        lib = self.read(src / "lib.rs")
        for module, names in re.findall(r"pub(?:\([^)]*\))?\s+use\s+(\w+)::([^;]*);", lib):
            exported.update({name: module for name in re.findall(r"\b(\w+)\b(?!\s*::)", names)})
        for path in self.files:
            top = path.relative_to(src).parts[0].removesuffix(".rs")
            if top not in self.edges or is_test_file(path, src):
                continue
            for line, name in crate_names(rust_strip(self.read(path))):
                dst = name if name in self.edges else exported.get(name, "")
                if dst in self.edges and dst != top:
                    self.edges[top].add(dst)
                    self.sites.setdefault((top, dst), []).append(
                        f"{path.relative_to(src.parent.parent)}:{line}"
                    )

    def read(self, path: Path) -> str:
        try:
            return path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            self.problems.append(f"{path}: cannot read: {exc}")
            return ""


def cycles(edges: Edges) -> list[list[str]]:
    """Strongly connected components of more than one node (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []
    sys.setrecursionlimit(max(1000, 4 * len(edges)))

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for nxt in sorted(edges[node]):
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = [stack.pop()]
            while component[-1] != node:
                component.append(stack.pop())
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(edges):
        if node not in index:
            visit(node)
    return sorted(found)


def levels(edges: Edges, cyc: list[list[str]]) -> list[list[str]]:
    """Level 0 imports nothing else, level k only lower levels; a cycle's modules share a level."""
    rep = {node: node for node in edges} | {m: comp[0] for comp in cyc for m in comp}
    deps: Edges = {r: set() for r in rep.values()}
    for node, targets in edges.items():
        deps[rep[node]] |= {rep[t] for t in targets} - {rep[node]}
    level: dict[str, int] = {}
    while len(level) < len(deps):
        for r in sorted(set(deps) - set(level)):
            if deps[r] <= set(level):
                level[r] = 1 + max((level[d] for d in deps[r]), default=-1)
    out: list[list[str]] = [[] for _ in range(1 + max(level.values(), default=-1))]
    for node in sorted(edges):
        out[level[rep[node]]].append(node)
    return out


def cycle_lines(edges: Edges, sites: Sites, cyc: list[list[str]]) -> list[str]:
    lines = []
    for comp in cyc:
        lines.append("cycle: " + " <-> ".join(comp))
        lines += [
            f"  {w}: {a} -> {b}" for a in comp for b in sorted(edges[a] & set(comp)) for w in sites[a, b]
        ]
    return lines


def oversize(files: list[Path], limit: int, root: Path) -> list[str]:
    out = []
    for path in files:
        n = len(path.read_text(encoding="utf-8", errors="replace").splitlines()) if path.exists() else 0
        if n > limit:
            out.append(f"{path.relative_to(root)}: {n} lines (limit {limit})")
    return out


def report(root: Path, rust: bool = False) -> dict[str, object]:
    """The whole report as data; `problems` is empty when the tree passes."""
    py = PythonGraph(root / "python" / "fakeack")
    cyc = cycles(py.edges)
    py_files = [p for p in py.files.values() if p.suffix == ".py"]
    big = oversize(py_files, PY_LIMIT, root)
    out: dict[str, object] = {
        "modules": len(py.edges),
        "edges": sorted([a, b] for a in py.edges for b in py.edges[a]),
        "levels": levels(py.edges, cyc),
        "cycles": cyc,
        "private_imports": sum("private" in p for p in py.problems),
        "cli_imports": sum("library module" in p for p in py.problems),
        "oversize": big,
        "problems": py.problems + cycle_lines(py.edges, py.sites, cyc) + big,
    }
    if rust:
        rs = RustGraph(root / "rust" / "src")
        rcyc = cycles(rs.edges)
        rbig = oversize([p for p in rs.files if not is_test_file(p, rs.src)], RS_LIMIT, root)
        out["rust"] = {
            "modules": len(rs.edges),
            "edges": sorted([a, b] for a in rs.edges for b in rs.edges[a]),
            "levels": levels(rs.edges, rcyc),
            "cycles": rcyc,
            "oversize": rbig,
        }
        out["problems"] = [*out["problems"], *rs.problems, *cycle_lines(rs.edges, rs.sites, rcyc), *rbig]  # type: ignore[misc]
    return out


def print_graph(title: str, graph: dict[str, object]) -> None:
    edges: list[list[str]] = graph["edges"]  # type: ignore[assignment]
    lvls: list[list[str]] = graph["levels"]  # type: ignore[assignment]
    print(f"{title}: {graph['modules']} modules, {len(edges)} edges, {len(lvls)} levels")
    for k, mods in enumerate(lvls):
        print(f"  level {k}: {' '.join(mods)}")
    print("edges:")
    for src in sorted({a for a, _ in edges}):
        print(f"  {src} -> {', '.join(b for a, b in edges if a == src)}")
    print(f"cycles: {len(graph['cycles'])}")  # type: ignore[arg-type]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=Path(__file__).resolve().parent.parent)
    parser.add_argument("--json", action="store_true", help="machine-readable output")
    parser.add_argument("--rust", action="store_true", help="also the Rust crate's top-level modules")
    args = parser.parse_args(argv)
    out = report(args.root, args.rust)
    problems: list[str] = out["problems"]  # type: ignore[assignment]
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print_graph("python/fakeack", out)
        print(f"private cross-imports: {out['private_imports']}, CLI imports: {out['cli_imports']}")
        print(f"oversize (> {PY_LIMIT} lines): {len(out['oversize'])}")  # type: ignore[arg-type]
        if args.rust:
            rs: dict[str, object] = out["rust"]  # type: ignore[assignment]
            print_graph("rust/src (top-level modules; test code ignored)", rs)
            print(f"oversize (> {RS_LIMIT} lines): {len(rs['oversize'])}")  # type: ignore[arg-type]
        print(f"{len(problems)} problems" + "".join(f"\n  {p}" for p in problems))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
