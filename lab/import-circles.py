#!/usr/bin/env python3
"""Import circles between the files of each crate of the workspace.

For every crate root (a library's `src/lib.rs`, each binary's `main.rs`)
the module tree is read from its `mod` declarations (`#[path]` honoured).
Every path a file names that starts in the crate (`crate::`, `super::`,
`self::`, or a child module's name), in a `use` or in code, is resolved
to the file that defines the item, through `pub use` re-exports: `use
crate::config::ConfigError` depends on the file that defines
`ConfigError`, whether or not `config.rs` re-exports it.  A `pub use`
whose name the re-exporting file's own code does not use is followed,
not counted: such a file is a signpost to the item, not a user of it.
An item re-exported from another crate is no file of this one.  A glob
import (`use super::*`) depends on the module's own file.  An inline
module (`mod tests { ... }`) belongs to its file, tests included.

A circle is a strongly connected set of two or more files; each is
printed with the imports that close it (the first of each file's
imports of another, with a count of the rest).  Exit status 1 when
there is one.

    python3 lab/import-circles.py [WORKSPACE]
"""

from __future__ import annotations

import re
import sys
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

ITEM = re.compile(r"\b(?:struct|enum|fn|trait|type|const|static|union|mod|macro_rules!)\s+(\w+)")
RAW_STRING = re.compile(r'b?r(#*)"')
CHAR = re.compile(r"'(?:\\(?:u\{[0-9a-fA-F]+\}|x[0-9a-fA-F]{2}|.)|[^\\'])'")
TOKEN = re.compile(
    r"(?P<use>\b(?P<pub>pub(?:\s*\([^)]*\))?\s+)?use\s+(?P<tree>[^;]+);)"
    r"|(?P<mod>\bmod\s+(?:r#)?(?P<modname>\w+)\s*(?P<modend>[;{]))"
    r"|(?P<open>\{)|(?P<close>\})"
    r"|(?P<path>(?<![$\w])(?:crate|super|self)(?:\s*::\s*(?:r#)?\w+)+)"
)
USE = re.compile(r"\buse\s+[^;]+;")
PATH_ATTR = re.compile(
    r'#\[path\s*=\s*"([^"]+)"\]\s*(?:#\[[^\]]*\]\s*)*(?:pub(?:\([^)]*\))?\s+)?mod\s+(\w+)\s*;'
)


def strip_code(src: str) -> str:
    """The source with comments, strings and char literals blanked (newlines kept)."""
    out = []
    i, n = 0, len(src)

    def blank(text: str) -> str:
        return "".join("\n" if c == "\n" else " " for c in text)

    while i < n:
        c = src[i]
        after_word = i > 0 and (src[i - 1].isalnum() or src[i - 1] == "_")
        raw = None if after_word else RAW_STRING.match(src, i)
        if src.startswith("//", i):
            j = src.find("\n", i)
            j = n if j < 0 else j
        elif src.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                if src.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif src.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
        elif raw:
            end = '"' + raw.group(1)
            j = src.find(end, raw.end())
            j = n if j < 0 else j + len(end)
        elif c == '"':
            j = i + 1
            while j < n and src[j] != '"':
                j += 2 if src[j] == "\\" else 1
            j += 1
        elif c == "'" and (m := CHAR.match(src, i)):
            # A char literal ('x', '\n', '\u{7f}', '\''), not a lifetime ('a).
            j = m.end()
        else:
            out.append(c)
            i += 1
            continue
        out.append(blank(src[i:j]))
        i = j
    return "".join(out)


def parse_use_tree(text: str) -> list[tuple[list[str], str]]:
    """`a::{b, c::d as e, f::*}` as (segments, the name it binds; '*' for a glob)."""
    text = re.sub(r"\s+", " ", text).strip()
    tokens = re.findall(r"::|[{},*]|\bas\b|(?:r#)?\w+", text)
    pos = 0

    def tree(prefix: list[str]) -> list[tuple[list[str], str]]:
        nonlocal pos
        segs = list(prefix)
        while pos < len(tokens):
            tok = tokens[pos]
            pos += 1
            if tok == "{":
                items = []
                while pos < len(tokens) and tokens[pos] != "}":
                    items += tree(segs)
                    if pos < len(tokens) and tokens[pos] == ",":
                        pos += 1
                pos += 1
                return items
            if tok == "*":
                return [(segs, "*")]
            name = tok.removeprefix("r#")
            if pos < len(tokens) and tokens[pos] == "::":
                pos += 1
                segs.append(name)
                continue
            alias = name
            if pos + 1 < len(tokens) and tokens[pos] == "as":
                alias = tokens[pos + 1]
                pos += 2
            if name == "self":
                if not segs:
                    return []
                return [(segs, segs[-1] if alias == "self" else alias)]
            return [(segs + [name], alias)]
        return []

    return tree([])


@dataclass
class Module:
    path: tuple[str, ...]
    file: Path
    inline: bool
    children: set[str] = field(default_factory=set)
    # Names its `pub use` binds, and its `pub use ...::*` globs, each as
    # written: relative to the module.
    exports: dict[str, list[str]] = field(default_factory=dict)
    globs: list[list[str]] = field(default_factory=list)
    defines: set[str] = field(default_factory=set)


@dataclass
class Reference:
    module: tuple[str, ...]  # the (possibly inline) module it is written in
    segments: list[str]
    line: int
    text: str
    reexport: str | None = None  # the name a `pub use` binds ('*': a glob)


class Crate:
    def __init__(self, name: str, root: Path):
        self.name = name
        self.modules: dict[tuple[str, ...], Module] = {}
        self.refs: dict[Path, list[Reference]] = {}
        self.words: dict[Path, set[str]] = {}
        self.load(root, (), root.name in ("lib.rs", "main.rs", "mod.rs"))

    def load(self, file: Path, path: tuple[str, ...], owns_dir: bool) -> None:
        raw = file.read_text()
        path_attrs = {name: target for target, name in PATH_ATTR.findall(raw)}
        code = strip_code(raw)
        # Where this file's `mod x;` children live.
        child_dir = file.parent if owns_dir else file.parent / file.stem
        self.modules[path] = Module(path, file, inline=False)
        refs = self.refs.setdefault(file, [])
        # The inline modules open at this point, with the depth each began at.
        stack: list[tuple[tuple[str, ...], int]] = [(path, -1)]
        depth = 0
        for m in TOKEN.finditer(code):
            line = code.count("\n", 0, m.start()) + 1
            cur = stack[-1][0]
            if m.group("open"):
                depth += 1
            elif m.group("close"):
                depth -= 1
                if len(stack) > 1 and stack[-1][1] == depth:
                    stack.pop()
            elif m.group("mod"):
                name = m.group("modname")
                self.modules[cur].children.add(name)
                if m.group("modend") == "{":
                    inner = cur + (name,)
                    self.modules[inner] = Module(inner, file, inline=True)
                    stack.append((inner, depth))
                    depth += 1
                    continue
                if name in path_attrs:
                    target = (file.parent / path_attrs[name]).resolve()
                    sub_owns = target.name == "mod.rs"
                else:
                    single, folder = child_dir / f"{name}.rs", child_dir / name / "mod.rs"
                    target, sub_owns = (single, False) if single.exists() else (folder, True)
                if target.exists():
                    self.load(target, cur + (name,), sub_owns)
            elif m.group("use"):
                text = " ".join(m.group(0).split())
                public = m.group("pub") is not None
                for segs, alias in parse_use_tree(m.group("tree")):
                    refs.append(Reference(cur, segs, line, text, alias if public else None))
                    if public and alias == "*":
                        self.modules[cur].globs.append(segs)
                    elif public:
                        self.modules[cur].exports[alias] = segs
            elif m.group("path"):
                segs = re.sub(r"\s+|r#", "", m.group("path")).split("::")
                refs.append(Reference(cur, segs, line, m.group("path")))
        for mod in self.modules.values():
            if mod.file == file:
                mod.defines = set(ITEM.findall(code))
        # The names the file's own code uses, its `use` statements left out.
        self.words[file] = set(re.findall(r"\w+", USE.sub(" ", code)))

    def absolute(self, cur: tuple[str, ...], segs: list[str]) -> tuple[str, ...] | None:
        """A path written in module `cur` as a path from the crate root; None outside it."""
        if not segs:
            return None
        if segs[0] == "crate":
            return tuple(segs[1:])
        if segs[0] in ("super", "self"):
            base = list(cur)
            rest = list(segs)
            while rest and rest[0] in ("super", "self"):
                if rest.pop(0) == "super":
                    if not base:
                        return None
                    base.pop()
            return tuple(base + rest)
        if cur in self.modules and segs[0] in self.modules[cur].children:
            return cur + tuple(segs)
        return None

    def resolve(self, path: tuple[str, ...], seen: frozenset = frozenset()) -> Path | None:
        """The file that defines what `path` names; None for another crate's item."""
        for k in range(len(path), -1, -1):
            mod = self.modules.get(path[:k])
            if mod is None:
                continue
            rest = path[k:]
            if not rest or mod.inline or (mod.path, rest[0]) in seen:
                return mod.file
            seen = seen | {(mod.path, rest[0])}
            name = rest[0]
            if name in mod.exports:
                target = self.absolute(mod.path, mod.exports[name])
                return self.resolve(target + rest[1:], seen) if target is not None else None
            if name not in mod.defines:
                for glob in mod.globs:
                    base = self.absolute(mod.path, glob)
                    inner = self.modules.get(base) if base is not None else None
                    if inner and (name in inner.defines or name in inner.exports):
                        return self.resolve(base + rest, seen)
            return mod.file
        return None

    def uses_reexport(self, file: Path, name: str, path: tuple[str, ...]) -> bool:
        """Whether a file's own code uses a name it re-exports (for a glob: any of them)."""
        words = self.words[file]
        if name != "*":
            return name in words
        inner = self.modules.get(path)
        return inner is None or bool((inner.defines | set(inner.exports)) & words)

    def edges(self) -> dict[Path, dict[Path, list[Reference]]]:
        graph: dict[Path, dict[Path, list[Reference]]] = {f: {} for f in self.refs}
        for file, refs in self.refs.items():
            for ref in refs:
                path = self.absolute(ref.module, ref.segments)
                if path is None:
                    continue
                if ref.reexport and not self.uses_reexport(file, ref.reexport, path):
                    continue
                target = self.resolve(path)
                if target is not None and target != file:
                    graph[file].setdefault(target, []).append(ref)
        return graph


def circles(graph: dict[Path, dict[Path, list[Reference]]]) -> list[list[Path]]:
    """Tarjan's strongly connected components of two or more files."""
    index: dict[Path, int] = {}
    low: dict[Path, int] = {}
    stack: list[Path] = []
    on: set[Path] = set()
    found: list[list[Path]] = []

    def visit(v: Path) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, {}):
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
                found.append(sorted(comp))

    sys.setrecursionlimit(10_000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(found)


def crate_roots(workspace: Path) -> list[tuple[str, Path]]:
    manifest = tomllib.loads((workspace / "Cargo.toml").read_text())
    roots = []
    for member in manifest["workspace"]["members"]:
        folder = workspace / member
        package = tomllib.loads((folder / "Cargo.toml").read_text())
        lib = package.get("lib", {}).get("path", "src/lib.rs")
        if (folder / lib).exists():
            roots.append((f"{member} (lib)", folder / lib))
        bins = {b["name"]: folder / b["path"] for b in package.get("bin", []) if "path" in b}
        if (folder / "src/main.rs").exists():
            bins.setdefault(package["package"]["name"], folder / "src/main.rs")
        for main in sorted((folder / "src/bin").glob("*/main.rs")):
            bins.setdefault(main.parent.name, main)
        for single in sorted((folder / "src/bin").glob("*.rs")):
            bins.setdefault(single.stem, single)
        roots += [(f"{member} (bin {name})", path) for name, path in sorted(bins.items())]
    return roots


def main() -> int:
    workspace = Path(sys.argv[1] if len(sys.argv) > 1 else ".").resolve()
    roots = crate_roots(workspace)
    total = 0
    for name, root in roots:
        graph = Crate(name, root).edges()
        for comp in circles(graph):
            total += 1
            members = set(comp)
            print(f"{name}: circle of {len(comp)} files")
            for f in comp:
                for g, refs in sorted(graph[f].items()):
                    if g in members:
                        more = f" (+{len(refs) - 1} more)" if len(refs) > 1 else ""
                        where = f"{f.relative_to(workspace)}:{refs[0].line}"
                        print(f"  {where} -> {g.relative_to(workspace)}: {refs[0].text}{more}")
    files = sum(1 for _ in workspace.glob("*/src/**/*.rs"))
    print(f"{total} import circle(s) in {len(roots)} crate roots ({files} source files)")
    return 1 if total else 0


if __name__ == "__main__":
    sys.exit(main())
