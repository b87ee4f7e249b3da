#!/usr/bin/env python3
"""Lists the functions longer than a limit in a tree of Rust sources.

Usage: long_functions.py [DIR...] [--limit N]

DIR defaults to every crate's src/ and examples/ (crates/*, and the Bevy
plugin, integrations/bevy_snowpack), N to 80. A function's length is its
lines from the line of `fn` to the line of its closing brace, both counted;
a function nested in another (or in a closure) counts for both. Comments and
the insides of string and character literals are blanked first, so a brace in
them does not count. Prints `LINES PATH:LINE NAME`, longest first, then the
count; exits 1 when there is one, so it can gate a CI run.

crates/snowpack/tests/layering.rs (`no_function_is_longer_than_the_limit`)
holds the same limit over the same folders as a test.
"""
import os
import re
import sys


def code_only(text):
    """`text` with comments and literal insides blanked, newlines kept."""
    out = []
    k, n = 0, len(text)

    def blank(ch):
        out.append("\n" if ch == "\n" else " ")

    while k < n:
        c = text[k]
        nxt = text[k + 1] if k + 1 < n else ""
        ident_before = k > 0 and (text[k - 1].isalnum() or text[k - 1] == "_")
        if c == "/" and nxt == "/":
            while k < n and text[k] != "\n":
                blank(text[k])
                k += 1
        elif c == "/" and nxt == "*":
            depth = 0
            while k < n:
                if text.startswith("/*", k):
                    depth += 1
                    out.append("  ")
                    k += 2
                elif text.startswith("*/", k):
                    depth -= 1
                    out.append("  ")
                    k += 2
                    if depth == 0:
                        break
                else:
                    blank(text[k])
                    k += 1
        elif not ident_before and re.match(r'b?r#*"', text[k:k + 260]):
            head = re.match(r'b?r(#*)"', text[k:]).group(0)
            close = '"' + "#" * (len(head) - text[k:].index("r") - 2)
            out.append(" " * len(head))
            k += len(head)
            end = text.find(close, k)
            end = n if end < 0 else end
            for ch in text[k:end]:
                blank(ch)
            out.append(" " * len(close))
            k = end + len(close)
        elif c == '"' or (c == "'" and (nxt == "\\" or (nxt not in ("'", "") and k + 2 < n and text[k + 2] == "'"))):
            out.append(" ")
            k += 1
            while k < n and text[k] != c:
                step = 2 if text[k] == "\\" else 1
                for ch in text[k:k + step]:
                    blank(ch)
                k += step
            out.append(" ")
            k += 1
        else:
            out.append(c)
            k += 1
    return "".join(out)


def functions(code):
    """(name, first line, last line) of every function with a body in `code`."""
    found = []
    for m in re.finditer(r"\bfn\s+([A-Za-z_][A-Za-z0-9_]*)", code):
        # The body opens at the first `{` outside the signature's brackets;
        # a `;` first means a declaration without a body (a trait method).
        depth, k = 0, m.end()
        while k < len(code):
            ch = code[k]
            if ch in "([<":
                depth += 1
            elif ch in ")]>" and not (ch == ">" and code[k - 1] == "-"):
                depth -= 1
            elif ch == ";" and depth <= 0:
                k = -1
                break
            elif ch == "{" and depth <= 0:
                break
            k += 1
        if k < 0 or k >= len(code):
            continue
        braces, j = 0, k
        while j < len(code):
            if code[j] == "{":
                braces += 1
            elif code[j] == "}":
                braces -= 1
                if braces == 0:
                    break
            j += 1
        first = code.count("\n", 0, m.start()) + 1
        last = code.count("\n", 0, j) + 1
        found.append((m.group(1), first, last))
    return found


def main():
    args = [a for a in sys.argv[1:]]
    limit = 80
    if "--limit" in args:
        i = args.index("--limit")
        limit = int(args[i + 1])
        del args[i:i + 2]
    repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    if not args:
        crates = [os.path.join("crates", c) for c in sorted(os.listdir(os.path.join(repo, "crates")))]
        crates.append(os.path.join("integrations", "bevy_snowpack"))
        args = [os.path.join(c, d) for c in crates for d in ("src", "examples") if os.path.isdir(os.path.join(repo, c, d))]
        os.chdir(repo)
    long = []
    walked = [(dirpath, names) for root in args for dirpath, _, names in os.walk(root)]
    for dirpath, names in walked:
        for name in sorted(names):
            if not name.endswith(".rs"):
                continue
            path = os.path.join(dirpath, name)
            with open(path, encoding="utf-8") as f:
                code = code_only(f.read())
            for fn, first, last in functions(code):
                lines = last - first + 1
                if lines > limit:
                    long.append((lines, f"{path}:{first}", fn))
    for lines, where, fn in sorted(long, key=lambda t: (-t[0], t[1])):
        print(f"{lines:5} {where} {fn}")
    print(f"{len(long)} function(s) over {limit} lines under {', '.join(args)}")
    sys.exit(1 if long else 0)


if __name__ == "__main__":
    main()
