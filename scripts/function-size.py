#!/usr/bin/env python3
"""Functions longer than a screen or two: lists every function (and lambda-free method body)
in clearfit's sources whose body spans more than LIMIT lines (default 150), and exits 1 if any.

A function here is a brace block at namespace scope (or a class member defined inside a class
at namespace scope) whose header holds a parameter list. Comments, string and character
literals (raw strings included) are skipped. Usage: scripts/function-size.py [--limit N] [ROOT]
"""
import argparse
import pathlib
import re
import sys

MODULES = ["core", "geometry", "camera", "refraction", "fit", "reports", "study", "cli", "bench"]


def strip_code(text):
    """The text with comments and literals blanked (newlines kept, so line numbers hold)."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append("\n" * text.count("\n", i, j))
            i = j
        elif c == "R" and text.startswith('R"', i) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            k = text.find("(", i + 2)
            delim = text[i + 2:k]
            j = text.find(")" + delim + '"', k)
            j = n if j < 0 else j + len(delim) + 2
            out.append('""' + "\n" * text.count("\n", i, j))
            i = j
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == "\\" else 1
            out.append(c + c)
            i = j + 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def long_functions(path, limit):
    code = strip_code(path.read_text(encoding="utf-8", errors="replace"))
    code = re.sub(r"^[ \t]*#.*$", "", code, flags=re.M)  # preprocessor lines
    found = []
    stack = []  # kinds of the open blocks: "ns" (transparent), "class", "fn", "other"
    header_start = 0  # index where the current statement's header began
    line = 1
    fn_start = None
    for i, c in enumerate(code):
        if c == "\n":
            line += 1
        elif c in ";":
            if not stack or stack[-1] in ("ns", "class"):
                header_start = i + 1
        elif c == "{":
            header = code[header_start:i]
            head = " ".join(header.split())
            outer = all(k in ("ns", "class") for k in stack)
            if not outer:
                stack.append("other")
            elif re.match(r"^(inline\s+)?namespace\b|^extern\s+\"", head):
                stack.append("ns")
            elif re.match(r"^(template\s*<.*>\s*)?(class|struct|union)\b", head) and "(" not in head.split("{")[0].split(":")[0]:
                stack.append("class")
            elif "(" in head and not re.match(r"^(enum)\b", head) and "=" not in head.split("(")[0]:
                stack.append("fn")
                fn_start = (line, head[:90])
            else:
                stack.append("other")
            header_start = i + 1
        elif c == "}":
            kind = stack.pop() if stack else "other"
            if kind == "fn" and fn_start:
                length = line - fn_start[0]
                if length > limit:
                    found.append((length, fn_start[0], fn_start[1]))
                fn_start = None
            if not stack or stack[-1] in ("ns", "class"):
                header_start = i + 1
    return found


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", nargs="?", default=pathlib.Path(__file__).resolve().parent.parent)
    ap.add_argument("--limit", type=int, default=150)
    a = ap.parse_args()
    root = pathlib.Path(a.root)
    bad = 0
    for module in MODULES:
        for path in sorted((root / module).rglob("*.[ch]pp")):
            for length, start, head in long_functions(path, a.limit):
                print(f"{path.relative_to(root)}:{start}: {length} lines: {head}")
                bad += 1
    print(f"{bad} function(s) longer than {a.limit} lines" if bad else f"every function is at most {a.limit} lines")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
