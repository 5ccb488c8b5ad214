#!/usr/bin/env python3
"""Import cycles between the crate's source files.

One node per module file under src/ (tests.rs files and `#[cfg(test)] mod tests`
blocks left out). An edge a -> b when a's code names a path into b: `use crate::..`,
`crate::..`, `super::..`, `self::..` or a child module's name (`csv::parse`), resolved
to the longest prefix that is a module file. Prints the cycles (strongly connected
components of more than one file) and exits 1 if there are any.
Usage: .ci/cycles.py [src]
"""
import os, re, sys

root = sys.argv[1] if len(sys.argv) > 1 else "src"
mods = {}  # module path tuple -> file
for d, _, fs in os.walk(root):
    for f in fs:
        if not f.endswith(".rs") or f == "tests.rs":
            continue
        p = os.path.join(d, f)
        rel = os.path.relpath(p, root)[:-3].split(os.sep)
        if rel in (["main"],) or rel[0] == "bin":
            continue
        if rel == ["lib"]:
            key = ()
        elif rel[-1] == "mod":
            key = tuple(rel[:-1])
        else:
            key = tuple(rel)
        mods[key] = p


def strip(text):
    """`text` with comments, strings and char literals blanked (a tiny Rust lexer)."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            i = n if j < 0 else j + 2
        elif c == "r" and re.match(r'r#*"', text[i:]) and not (i and (text[i - 1].isalnum() or text[i - 1] == "_")):
            hashes = re.match(r'r(#*)"', text[i:]).group(1)
            j = text.find('"' + hashes, i + 2 + len(hashes))
            out.append('""')
            i = n if j < 0 else j + 1 + len(hashes)
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            out.append('""')
            i = j + 1
        elif c == "'" and (re.match(r"'(\\.[^']*|[^'\\])'", text[i:])):
            m = re.match(r"'(\\.[^']*|[^'\\])'", text[i:])
            out.append("' '")
            i += m.end()
        else:
            out.append(c)
            i += 1
    return "".join(out)


def code(text):
    # Comments (doc links are not imports), strings, then the unit tests.
    text = strip(text)
    m = re.search(r"#\[cfg\(test\)\]\s*(pub(\(\w+\))?\s+)?mod\s+\w+\s*\{", text)
    if m:
        text = text[: m.start()]
    return text


def expand(tree):
    # `a::{b, c::{d, e}}` -> [a::b, a::c::d, a::c::e]
    tree = re.sub(r"\s+", "", tree)
    out, depth, start = [], 0, 0
    i = tree.find("{")
    if i < 0:
        return [tree]
    prefix, body = tree[:i], tree[i + 1 : tree.rfind("}")]
    parts, cur = [], ""
    for ch in body:
        if ch == "{":
            depth += 1
        elif ch == "}":
            depth -= 1
        if ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    parts.append(cur)
    for part in parts:
        if part:
            out += [prefix + x for x in expand(part)]
    return out


def resolve(base, segs):
    """Longest module-file prefix of base + segs."""
    path = list(base)
    for s in segs:
        if s == "super":
            path = path[:-1]
        elif s == "self":
            pass
        elif s == "crate":
            path = []
        else:
            path.append(s)
    best = None
    for n in range(len(path), -1, -1):
        if tuple(path[:n]) in mods:
            best = tuple(path[:n])
            break
    return best


edges = {k: set() for k in mods}
for key, f in mods.items():
    text = code(open(f).read())
    # The base for `super::` is the file's own module.
    paths = []
    for m in re.finditer(r"\buse\s+([^;]+);", text):
        for p in expand(m.group(1)):
            p = re.sub(r"as\w+$", "", p)
            paths.append(p)
    for m in re.finditer(r"(?<![\w:])((?:crate|super|self)(?:::\w+)+)", text):
        paths.append(m.group(1))
    children = {k[-1] for k in mods if len(k) == len(key) + 1 and k[: len(key)] == key}
    for c in children:
        if re.search(r"(?<![\w:])" + c + r"::", text):
            paths.append("self::" + c)
    for p in paths:
        segs = p.split("::")
        if segs[0] not in ("crate", "super", "self"):
            if segs[0] in children:
                segs = ["self"] + segs
            else:
                continue
        t = resolve(key, segs)
        if t is not None and t != key:
            edges[key].add(t)

# Tarjan's strongly connected components.
index, low, stack, on, sccs, n = {}, {}, [], set(), [], [0]
sys.setrecursionlimit(10000)


def visit(v):
    index[v] = low[v] = n[0]
    n[0] += 1
    stack.append(v)
    on.add(v)
    for w in edges[v]:
        if w not in index:
            visit(w)
            low[v] = min(low[v], low[w])
        elif w in on:
            low[v] = min(low[v], index[w])
    if low[v] == index[v]:
        c = []
        while True:
            w = stack.pop()
            on.discard(w)
            c.append(w)
            if w == v:
                break
        sccs.append(c)


for v in sorted(mods):
    if v not in index:
        visit(v)
name = lambda k: mods[k]
cyc = [sorted(c) for c in sccs if len(c) > 1]
for c in cyc:
    print("cycle:", " ".join(name(k) for k in c))
    for a in c:
        for b in sorted(edges[a]):
            if b in c:
                print("   ", name(a), "->", name(b))
print(f"{len(mods)} files, {sum(map(len, edges.values()))} edges, {len(cyc)} cycles")
sys.exit(1 if cyc else 0)
