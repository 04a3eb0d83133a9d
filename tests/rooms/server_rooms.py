#!/usr/bin/env python3
"""The walls of server/ (docs/development/architecture.md): which room may include which, and who alone may speak
SQLite, SQL and HTTP. Run by ctest (server_rooms); `--measure` prints the numbers the layout is
judged by (files and lines per room, the longest functions, SQL-bearing files, include cycles).

Rooms and the direction they may look (each also sees core/ and platform/):
  server/ (root: main, periodic, local workers) -> every room
  http -> jobs, analysis, dashboard, store
  jobs, analysis, dashboard -> store
  store -> nothing in server/
Rules, for every non-test source of server/ (tests link the whole daemon and may look anywhere):
  - it includes server headers only of its own room or of the rooms it may look at;
  - only server/store/ includes sqlite3.h or holds SQL text;
  - only server/http/ includes the HTTP library (httplib.h);
  - no include cycle among server/'s files (a header and its .cc count as one).
Exit status 1 with one line per breach, saying the file, the rule and what to do.
"""
import os
import re
import sys

ROOT = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 and not sys.argv[1].startswith("-") else
                       os.path.join(os.path.dirname(__file__), "..", ".."))
SERVER = os.path.join(ROOT, "server")
MAY_SEE = {
    "": {"", "http", "jobs", "analysis", "dashboard", "store"},
    "http": {"http", "jobs", "analysis", "dashboard", "store"},
    "jobs": {"jobs", "store"},
    "analysis": {"analysis", "store"},
    "dashboard": {"dashboard", "store"},
    "store": {"store"},
}
INCLUDE = re.compile(r'^\s*#\s*include\s*[<"]([^>"]+)[>"]', re.M)
# SQL text: a string literal that opens with a statement's keyword.
SQL = re.compile(r'"\s*(SELECT|INSERT|UPDATE|DELETE|BEGIN|COMMIT|ROLLBACK|SAVEPOINT|RELEASE|PRAGMA|CREATE|DROP|'
                 r'ALTER|WITH|VACUUM|ANALYZE|REPLACE)\b[ A-Za-z_(*,]')


def sources():
    for d, dirs, files in os.walk(SERVER):
        dirs[:] = [x for x in dirs if x not in ("node_modules",)]
        for f in sorted(files):
            if f.endswith((".cc", ".h")):
                yield os.path.relpath(os.path.join(d, f), ROOT)


def room(path):  # "server/http/routes.cc" -> "http"; "server/main.cc" -> ""
    parts = path.split("/")
    return parts[1] if len(parts) > 2 else ""


def is_test(path):
    return path.endswith(("_test.cc", "_test_util.h", "_test_util.cc", "test_support.h", "test_support.cc"))


def module(path):
    return re.sub(r"\.(cc|h)$", "", path)


def read(path):
    with open(os.path.join(ROOT, path), encoding="utf-8") as f:
        return f.read()


def cycles(files):
    graph = {}
    for p in files:
        m = module(p)
        graph.setdefault(m, set())
        for inc in INCLUDE.findall(read(p)):
            if inc.startswith("server/") and module(inc) != m:
                graph[m].add(module(inc))
    # Tarjan's strongly connected components.
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
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

    sys.setrecursionlimit(10000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def check():
    breaches = []
    files = [p for p in sources() if not is_test(p)]
    for p in files:
        text = read(p)
        r = room(p)
        for inc in INCLUDE.findall(text):
            if inc.startswith("server/"):
                target = room(inc)
                if target not in MAY_SEE.get(r, set()):
                    breaches.append(f"{p}: includes {inc}, but server/{r or ''} may not look at "
                                    f"server/{target}: move the shared part down a room (store, or core/)")
            if inc == "sqlite3.h" and r != "store":
                breaches.append(f"{p}: includes sqlite3.h outside server/store/: read and write through the Store")
            if inc == "httplib.h" and r != "http":
                breaches.append(f"{p}: includes httplib.h outside server/http/: keep the HTTP library in server/http/")
        if r != "store" and SQL.search(text):
            breaches.append(f"{p}: holds SQL text outside server/store/: make it a Store method or a "
                            f"store-side table's")
    for c in cycles(files):
        breaches.append("include cycle: " + " -> ".join(c) + ": split the shared declarations into their own header")
    for b in breaches:
        print(b)
    return 1 if breaches else 0


def longest_functions(files, n=10):
    found = []
    for p in files:
        lines = read(p).split("\n")
        i = 0
        while i < len(lines):
            line = lines[i]
            # A definition at namespace scope: a line at column 0 that is not a preprocessor line,
            # comment or closing brace and whose statement opens a body at column 0 or at its end.
            if line and not line[0].isspace() and not line.startswith(("#", "//", "}", "namespace", "using",
                                                                         "struct", "class", "enum", "static_assert")) \
                    and "(" in line:
                j = i
                while j < len(lines) and not lines[j].rstrip().endswith(("{", ";", "}")):
                    j += 1
                if j < len(lines) and lines[j].rstrip().endswith("{"):
                    k = j + 1
                    while k < len(lines) and lines[k] != "}" and not lines[k].startswith("}"):
                        k += 1
                    name = re.match(r"[^(]*?([A-Za-z_][A-Za-z_0-9:~]*)\s*\(", line)
                    found.append((k - i + 1, f"{p}:{i + 1} {name.group(1) if name else line[:40]}"))
                    i = k
            i += 1
    return sorted(found, reverse=True)[:n]


def measure():
    files = list(sources())
    per_room = {}
    for p in files:
        r = room(p) or "(root)"
        n = read(p).count("\n")
        f, l = per_room.get(r, (0, 0))
        per_room[r] = (f + 1, l + n)
    print("files and lines per room (tests included):")
    for r, (f, l) in sorted(per_room.items()):
        print(f"  {r:10s} {f:4d} files {l:6d} lines")
    non_test = [p for p in files if not is_test(p)]
    sql = [p for p in non_test if SQL.search(read(p))]
    print(f"non-test files with SQL text: {len(sql)}: {' '.join(sql)}")
    sql_t = [p for p in files if is_test(p) and SQL.search(read(p))]
    print(f"test files with SQL text: {len(sql_t)}: {' '.join(sql_t)}")
    print("include cycles (non-test):", cycles(non_test) or "none")
    print("longest functions:")
    for n, where in longest_functions([p for p in non_test if p.endswith(".cc")]):
        print(f"  {n:4d} lines  {where}")


if __name__ == "__main__":
    if "--measure" in sys.argv:
        measure()
        sys.exit(0)
    sys.exit(check())
