#!/usr/bin/env python3
"""Lists the C++ functions longer than a bound (lines from the opening brace to the closing
one, the signature's last line included), longest first, and exits 1 when there is any.

    python3 tools/function_lengths.py [--max 100] [DIR ...]     (default: src drivers tools)

A brace counter, not a parser: comments, string and character literals are blanked first;
a brace opens a function when the text before it ends in a parameter list (optionally
followed by const, noexcept, override, a trailing return type or a constructor's
initialiser list) and is not a control statement, a lambda, a class or a namespace. Lambdas
and nested blocks count towards the function they are in."""

import argparse
import os
import re
import sys

CONTROL = re.compile(r"\b(if|for|while|switch|catch)\s*\($")
SCOPE = re.compile(r"\b(class|struct|namespace|enum|union)\b")
PARAMS_END = re.compile(r"\)\s*(const|noexcept|override|final|mutable|->\s*[\w:<>,\s*&]+|\s)*$")
LAMBDA = re.compile(r"\[[^\]]*\]\s*\([^)]*\)\s*(mutable\s*)?(->[^{]*)?$")


def blank(text):
    """Comments and literals replaced by blanks, line breaks kept."""
    keep_lines = lambda m: "\n" * m.group(0).count("\n")
    text = re.sub(r"//[^\n]*", "", text)
    text = re.sub(r"/\*.*?\*/", keep_lines, text, flags=re.S)
    text = re.sub(r'R"(\w*)\((.*?)\)\1"', lambda m: '""' + keep_lines(m), text, flags=re.S)
    text = re.sub(r'"(\\.|[^"\\\n])*"', '""', text)
    return re.sub(r"'(\\.|[^'\\\n])*'", "''", text)


def opens_function(head):
    statement = re.split(r"[;{}]", head)[-1]
    if SCOPE.search(statement):
        return False
    if not PARAMS_END.search(head.rstrip()) or LAMBDA.search(head.rstrip()):
        return False
    # "if (...) {", "for (...) {": the first parenthesis belongs to a control keyword.
    before_paren = statement.split("(")[0] + "("
    return not CONTROL.search(before_paren.strip()) and "=" not in statement.split("(")[0]


def functions(path):
    text = blank(open(path, errors="replace").read())
    stack = []
    for at, ch in enumerate(text):
        if ch == "{":
            kind = "function" if opens_function(text[max(0, at - 400):at]) else "block"
            stack.append((kind, text.count("\n", 0, at) + 1, at))
        elif ch == "}" and stack:
            kind, first, start = stack.pop()
            if kind == "function" and not any(k == "function" for k, _, _ in stack):
                name = re.split(r"[;{}]", text[max(0, start - 400):start])[-1]
                name = " ".join(name.split())[-70:]
                yield text.count("\n", 0, at) + 1 - first + 1, first, name


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--max", type=int, default=100, help="longest allowed, lines")
    parser.add_argument("dirs", nargs="*", default=["src", "drivers", "tools"])
    args = parser.parse_args()
    found = []
    for top in args.dirs:
        for folder, _, files in os.walk(top):
            for name in sorted(files):
                if name.endswith((".cpp", ".hpp")):
                    path = os.path.join(folder, name)
                    found += [(n, path, line, sig) for n, line, sig in functions(path) if n > args.max]
    for n, path, line, sig in sorted(found, reverse=True):
        print(f"{n} {path}:{line} {sig}")
    print(f"{len(found)} function(s) over {args.max} lines in {', '.join(args.dirs)}")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
