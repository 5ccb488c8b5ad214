#!/usr/bin/env python3
"""Functions longer than a limit (default 150 lines), from `fn` to its closing brace.

Scans the .rs files under the given roots (default src tests), unit tests included.
Comments, strings and char literals are blanked first, so braces in them do not count.
Prints `lines path:line name`, longest first; exits 1 if any.
Usage: .ci/long_fns.py [--max N] [root...]
"""
import os, re, sys

args = sys.argv[1:]
limit = 150
if args[:1] == ["--max"]:
    limit, args = int(args[1]), args[2:]
roots = args or ["src", "tests"]


def blank(t):
    """`t` with every character but newlines replaced by a space."""
    return re.sub(r"[^\n]", " ", t)


def strip(text):
    """`text` with comments, strings and char literals blanked, newlines kept (so line
    numbers and counts hold)."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
        elif c == "r" and re.match(r'r#*"', text[i:]) and not (i and (text[i - 1].isalnum() or text[i - 1] == "_")):
            hashes = re.match(r'r(#*)"', text[i:]).group(1)
            j = text.find('"' + hashes, i + 2 + len(hashes))
            j = n if j < 0 else j + 1 + len(hashes)
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            j += 1
        elif c == "'" and re.match(r"'(\\.[^']*|[^'\\])'", text[i:]):
            j = i + re.match(r"'(\\.[^']*|[^'\\])'", text[i:]).end()
        else:
            out.append(c)
            i += 1
            continue
        out.append(blank(text[i:j]))
        i = j
    return "".join(out)


FN = re.compile(r"\bfn\s+(\w+)")
found = []
for root in roots:
    for d, _, fs in os.walk(root):
        for f in sorted(fs):
            if not f.endswith(".rs"):
                continue
            p = os.path.join(d, f)
            text = strip(open(p).read())
            for m in FN.finditer(text):
                # The body's opening brace: the first `{` or `;` after the signature at
                # bracket depth 0 (a `;` is a declaration without a body).
                i, depth = m.end(), 0
                while i < len(text):
                    c = text[i]
                    if c in "(<[":
                        depth += 1
                    elif c in ")>]" and not (c == ">" and text[i - 1] == "-"):
                        depth -= 1
                    elif depth <= 0 and c in "{;":
                        break
                    i += 1
                if i >= len(text) or text[i] == ";":
                    continue
                j, level = i, 0
                while j < len(text):
                    if text[j] == "{":
                        level += 1
                    elif text[j] == "}":
                        level -= 1
                        if level == 0:
                            break
                    j += 1
                start = text.count("\n", 0, m.start()) + 1
                lines = text.count("\n", m.start(), j) + 1
                if lines > limit:
                    found.append((lines, f"{p}:{start}", m.group(1)))
for n, where, name in sorted(found, key=lambda x: (-x[0], x[1])):
    print(f"{n:5d} {where} {name}")
sys.exit(1 if found else 0)
