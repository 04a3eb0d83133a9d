#!/usr/bin/env python3
"""The docs check (ctest `docs_check`; docs/development/testing.md, "The docs check").

Fails, one line per finding, when
  - a relative link or anchor in README.md, CONTRIBUTING.md, CHANGELOG.md or docs/ does not resolve,
    or their prose names a section (under "X") that no page has;
  - the code cites a README heading (README "X") that README.md does not have, or a docs/ path
    (with its #anchor) that does not exist;
  - a page users read (the docs, the shipped campaigns) points at SPEC.md or ../shared/, files
    users do not have;
  - README.md is larger than 10 KB (it is one screen and a bit; the rest is in docs/);
  - a generated reference under docs/reference/ differs from what the code generates now: the
    CLI's and the daemons' --help, the result fields and the scales (sandswim-docgen), the REST
    API (schema/openapi.json).

Usage: check_docs.py --root REPO --bin BUILD/bin [--update]. --update rewrites the generated
references instead of comparing them (then run the check again).
"""
import argparse
import json
import os
import re
import subprocess
import sys

README_LIMIT = 10 * 1024
TOP_PAGES = ["README.md", "CONTRIBUTING.md", "CHANGELOG.md"]
# Where the code is: the files whose comments and messages may cite the docs.
CODE_DIRS = ["core", "server", "cli", "workers", "platform", "tests", "deploy", "schema", "templates", ".ci"]
CODE_EXT = (".h", ".cc", ".py", ".sh", ".txt", ".json", ".js", ".html", ".css", ".service", ".timer", ".sbatch",
            ".cmake", ".in", "run")
# The colleague-owned pages that are not written yet may be named by the code before they exist.
FUTURE_PAGES = {"docs/how-to/time-step.md", "docs/explanation/convergence.md"}


def md_files(root):
    out = [p for p in TOP_PAGES if os.path.exists(os.path.join(root, p))]
    for d, _, files in os.walk(os.path.join(root, "docs")):
        for f in sorted(files):
            if f.endswith(".md"):
                out.append(os.path.relpath(os.path.join(d, f), root))
    return sorted(out)


def prose_lines(text):
    """The lines of a Markdown text outside fenced and indented code blocks, with inline code removed."""
    lines, fenced, prev_blank, in_indented = [], False, True, False
    for n, line in enumerate(text.split("\n"), 1):
        if line.lstrip().startswith("```"):
            fenced = not fenced
            continue
        if fenced:
            continue
        if line.startswith("    ") and (prev_blank or in_indented):
            in_indented = True
            continue
        in_indented = False
        prev_blank = not line.strip()
        lines.append((n, re.sub(r"`[^`]*`", "", line)))
    return lines


def slug(heading):
    h = re.sub(r"`|\*\*|\*|_(?=\W)|\[|\]\([^)]*\)", "", heading).strip().lower()
    h = re.sub(r"[^\w\- ]", "", h)
    return h.replace(" ", "-")


def anchors(root, path, cache={}):
    if path not in cache:
        found, counts = set(), {}
        with open(os.path.join(root, path), encoding="utf-8") as f:
            for _, line in prose_lines(f.read()):
                m = re.match(r"#{1,6}\s+(.*?)\s*#*\s*$", line)
                if m:
                    s = slug(m.group(1))
                    k = counts.get(s, 0)
                    counts[s] = k + 1
                    found.add(s if k == 0 else f"{s}-{k}")
        cache[path] = found
    return cache[path]


def headings(root, path):
    with open(os.path.join(root, path), encoding="utf-8") as f:
        return [m.group(1) for _, line in prose_lines(f.read()) for m in [re.match(r"#{1,6}\s+(.*?)\s*$", line)] if m]


def check_links(root, problems):
    link = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
    for page in md_files(root):
        with open(os.path.join(root, page), encoding="utf-8") as f:
            text = f.read()
        for n, line in prose_lines(text):
            for target in link.findall(line):
                if re.match(r"[a-z]+:", target):
                    continue  # http:, https:, mailto:
                path, _, anchor = target.partition("#")
                dest = os.path.normpath(os.path.join(os.path.dirname(page), path)) if path else page
                if not os.path.exists(os.path.join(root, dest)):
                    problems.append(f"{page}:{n}: link to {target}: no such file {dest}")
                    continue
                if anchor and dest.endswith(".md") and anchor not in anchors(root, dest):
                    problems.append(f"{page}:{n}: link to {target}: {dest} has no heading #{anchor}")


def check_section_refs(root, problems):
    """A section named in prose (under "X", below, "X") must be a heading of some page: link it."""
    every = [h.lower() for p in md_files(root) for h in headings(root, p)]
    ref = re.compile(r"\b(?:[Uu]nder|[Bb]elow|[Aa]bove|[Ss]ee)(?:,| under| in)?\s+\"([A-Z][^\"]{2,80})\"")
    for page in md_files(root):
        with open(os.path.join(root, page), encoding="utf-8") as f:
            lines = prose_lines(f.read())
        # Paragraphs, so that a quoted name broken over two lines is seen whole.
        paragraphs, start, text = [], None, []
        for n, line in lines + [(0, "")]:
            if line.strip():
                start = start or n
                text.append(line)
            elif text:
                paragraphs.append((start, " ".join(text)))
                start, text = None, []
        for n, para in paragraphs:
            for h in ref.findall(para):
                h = " ".join(h.split())
                if not any(x.startswith(h.lower()) for x in every):
                    problems.append(f"{page}:{n}: refers to a section \"{h}\" that no page has (link the page)")


def code_files(root):
    for top in CODE_DIRS:
        for d, dirs, files in os.walk(os.path.join(root, top)):
            dirs[:] = [x for x in dirs if x not in ("node_modules", "build") and not x.startswith(".")]
            for f in files:
                if f.endswith(CODE_EXT) or f == "run":
                    yield os.path.join(d, f)
    for f in ("CMakeLists.txt",):
        yield os.path.join(root, f)


def check_citations(root, problems):
    readme = [h.lower() for h in headings(root, "README.md")]
    quoted = re.compile(r"(?<![/\w])README(?:\.md)?(?:'s)?,?:?\s*\(?[\"'\u201c]([A-Z][^\"'\u201d]*)[\"'\u201d]")
    unquoted = re.compile(r"(?<![/\w])README(?:\.md)?:\s+([A-Z][\w-]*(?: [a-z][\w-]*)*)")
    doc_path = re.compile(r"(?<![\w/.])((?:\.\./)*docs/[\w./-]+\.md)(#[\w-]+)?")
    for path in code_files(root):
        rel = os.path.relpath(path, root)
        if rel.startswith("docs/") or rel.startswith("tests/docs/"):
            continue
        try:
            with open(path, encoding="utf-8") as f:
                text = f.read()
        except (UnicodeDecodeError, OSError):
            continue
        for n, line in enumerate(text.split("\n"), 1):
            for h in quoted.findall(line) + unquoted.findall(line):
                if not any(x.startswith(h.lower()) for x in readme):
                    problems.append(f"{rel}:{n}: cites README \"{h}\", which README.md has no heading for "
                                    f"(cite the docs/ page that holds it)")
            for p, anchor in doc_path.findall(line):
                p = re.sub(r"^(\.\./)+", "", p)
                if p in FUTURE_PAGES:
                    continue
                if not os.path.exists(os.path.join(root, p)):
                    problems.append(f"{rel}:{n}: cites {p}, which does not exist")
                elif anchor and anchor[1:] not in anchors(root, p):
                    problems.append(f"{rel}:{n}: cites {p}{anchor}: no such heading")


def check_user_facing(root, problems):
    pages = md_files(root)
    camp = os.path.join(root, "templates", "campaigns")
    if os.path.isdir(camp):
        pages += [os.path.join("templates", "campaigns", f) for f in sorted(os.listdir(camp)) if f.endswith(".json")]
    for page in pages:
        with open(os.path.join(root, page), encoding="utf-8") as f:
            for n, line in enumerate(f.read().split("\n"), 1):
                if re.search(r"SPEC\.md|\.\./shared/", line):
                    problems.append(f"{page}:{n}: points at SPEC.md or ../shared/, which users do not have")


def check_readme_size(root, problems):
    size = os.path.getsize(os.path.join(root, "README.md"))
    if size > README_LIMIT:
        problems.append(f"README.md: {size} bytes, more than {README_LIMIT}: move the detail into docs/")


# ---- Generated references -------------------------------------------------------------------

def run_help(binary, args):
    env = {"PATH": os.environ.get("PATH", "/usr/bin:/bin"), "HOME": "/nonexistent", "NO_COLOR": "1",
           "COLUMNS": "120", "LANG": "C.UTF-8"}
    out = subprocess.run([binary] + args, capture_output=True, text=True, timeout=20, env=env, cwd="/")
    text = out.stdout + out.stderr
    return text.replace(os.path.dirname(binary) + "/", "")


def subcommands(help_text):
    """The subcommand names a CLI11 help lists under "Subcommands:"."""
    subs, in_subs = [], False
    for line in help_text.split("\n"):
        if line.startswith("Subcommands:"):
            in_subs = True
            continue
        if in_subs:
            m = re.match(r"  (\S+)\s", line)
            if m:
                subs.append(m.group(1))
            elif line.strip() == "":
                break
    return subs


def cli_reference(bindir):
    sandswim = os.path.join(bindir, "sandswim")
    top = run_help(sandswim, ["--help"])
    out = ["# Reference: command-line help", "",
           "Generated from the executables' `--help` by `tests/docs/check_docs.py --update`; do not edit by hand.",
           "Exit codes are in [exit codes](exit-codes.md).", "",
           "## sandswim", "", "```", top.rstrip(), "```", ""]
    for sub in subcommands(top):
        text = run_help(sandswim, [sub, "--help"])
        out += [f"### sandswim {sub}", "", "```", text.rstrip(), "```", ""]
        for inner in subcommands(text):
            out += [f"#### sandswim {sub} {inner}", "", "```",
                    run_help(sandswim, [sub, inner, "--help"]).rstrip(), "```", ""]
    for daemon in ("sandswimd", "sandswim-worker"):
        out += [f"## {daemon}", "", "```", run_help(os.path.join(bindir, daemon), ["--help"]).rstrip(), "```", ""]
    return "\n".join(out)


def docgen(bindir, page):
    return subprocess.run([os.path.join(bindir, "sandswim-docgen"), page], capture_output=True, text=True,
                          timeout=20, check=True).stdout


def md_cell(s):
    return " ".join(str(s).split()).replace("|", "\\|")


def schema_text(s):
    if not isinstance(s, dict):
        return ""
    if "$ref" in s:
        name = s["$ref"].split("/")[-1]
        return f"[{name}](schemas.md#{slug(name)})"
    for k in ("oneOf", "anyOf", "allOf"):
        if k in s:
            return (" or " if k != "allOf" else " and ").join(schema_text(x) for x in s[k])
    t = s.get("type", "")
    if t == "array":
        return f"array of {schema_text(s.get('items', {})) or 'values'}"
    if "enum" in s:
        return f"{t} (" + ", ".join(f"`{v}`" for v in s["enum"]) + ")"
    return t


def resource_of(path):
    m = re.match(r"/api/v1/([^/{]+)", path)
    if not m:
        return "operations"
    r = m.group(1)
    return {"openapi.json": "operations", "backup": "operations", "cost-model": "operations"}.get(r, r)


def api_reference(root):
    with open(os.path.join(root, "schema", "openapi.json"), encoding="utf-8") as f:
        api = json.load(f)
    note = "Generated from `schema/openapi.json` by `tests/docs/check_docs.py --update`; do not edit by hand."
    pages = {}
    for path, ops in api["paths"].items():
        res = resource_of(path)
        lines = pages.setdefault(res, [])
        for method, op in ops.items():
            if not isinstance(op, dict) or method == "parameters":
                continue
            lines += [f"## {method.upper()} {path}", ""]
            if op.get("summary"):
                lines += [md_cell(op["summary"]), ""]
            if op.get("description"):
                lines += [md_cell(op["description"]), ""]
            params = op.get("parameters", []) + ops.get("parameters", [])
            if params:
                lines += ["| parameter | in | required | type | what |", "| --- | --- | --- | --- | --- |"]
                for p in params:
                    lines.append(f"| `{p.get('name')}` | {p.get('in')} | {'yes' if p.get('required') else 'no'} | "
                                 f"{md_cell(schema_text(p.get('schema', {})))} | {md_cell(p.get('description', ''))} |")
                lines.append("")
            body = op.get("requestBody")
            if body:
                for ctype, c in body.get("content", {}).items():
                    lines += [f"Request body (`{ctype}`): {schema_text(c.get('schema', {})) or 'see the description'}", ""]
            lines += ["| status | what | body |", "| --- | --- | --- |"]
            for code, r in op.get("responses", {}).items():
                bodies = ", ".join(f"`{ct}` {schema_text(c.get('schema', {}))}".strip()
                                   for ct, c in r.get("content", {}).items())
                lines.append(f"| {code} | {md_cell(r.get('description', ''))} | {md_cell(bodies)} |")
            lines.append("")
    out = {}
    index = ["# Reference: the REST API", "", note, "", md_cell(api["info"].get("description", "")), "",
             "The daemon serves the description itself at `GET /api/v1/openapi.json`.", "",
             "| resource | routes |", "| --- | --- |"]
    for res in sorted(pages):
        ops = [l[3:] for l in pages[res] if l.startswith("## ")]
        index.append(f"| [{res}]({res}.md) | " + "<br>".join(f"`{o}`" for o in ops) + " |")
        out[f"docs/reference/api/{res}.md"] = "\n".join([f"# REST API: {res}", "", note, "",
                                                         "[All resources](index.md)", ""] + pages[res])
    index += ["", "The JSON types: [schemas](schemas.md).", ""]
    out["docs/reference/api/index.md"] = "\n".join(index)
    sch = ["# REST API: schemas", "", note, "", "[All resources](index.md)", ""]
    for name, s in api["components"]["schemas"].items():
        sch += [f"## {name}", ""]
        if s.get("description"):
            sch += [md_cell(s["description"]), ""]
        props = s.get("properties", {})
        if props:
            req = set(s.get("required", []))
            sch += ["| field | type | unit | required | what |", "| --- | --- | --- | --- | --- |"]
            for k, v in props.items():
                sch.append(f"| `{k}` | {md_cell(schema_text(v))} | {v.get('x-unit', '') if isinstance(v, dict) else ''} | "
                           f"{'yes' if k in req else 'no'} | {md_cell(v.get('description', '') if isinstance(v, dict) else '')} |")
            sch.append("")
        elif schema_text(s):
            sch += [f"Type: {schema_text(s)}", ""]
    out["docs/reference/api/schemas.md"] = "\n".join(sch)
    return out


def data_dir_reference(root):
    with open(os.path.join(root, "platform", "data_dir.h"), encoding="utf-8") as f:
        rows = [m.groups() for m in re.finditer(r"^//   (DATA/\S*)\s+(.*)$", f.read(), re.M)]
    out = ["# Reference: the data directory", "",
           "Generated from `platform/data_dir.h` (`DataDir`, the one place that spells these paths) by",
           "`tests/docs/check_docs.py --update`; do not edit by hand. DATA is `sandswimd --data` (default",
           "`./var/data`); the SQLite file is `--db` (default `./var/sandswim.db`), outside it.", "",
           "| path | what |", "| --- | --- |"]
    out += [f"| `{p}` | {md_cell(w)} |" for p, w in rows]
    return "\n".join(out)


def generated(root, bindir):
    out = {"docs/reference/cli.md": cli_reference(bindir),
           "docs/reference/result-fields.md": docgen(bindir, "result-fields"),
           "docs/reference/scales.md": docgen(bindir, "scales"),
           "docs/reference/data-dir.md": data_dir_reference(root)}
    out.update(api_reference(root))
    return {k: v.rstrip("\n") + "\n" for k, v in out.items()}


def check_generated(root, bindir, update, problems):
    for rel, text in sorted(generated(root, bindir).items()):
        path = os.path.join(root, rel)
        if update:
            os.makedirs(os.path.dirname(path), exist_ok=True)
            with open(path, "w", encoding="utf-8") as f:
                f.write(text)
            continue
        try:
            with open(path, encoding="utf-8") as f:
                committed = f.read()
        except OSError:
            committed = None
        if committed != text:
            problems.append(f"{rel}: differs from what the code generates now "
                            f"(run tests/docs/check_docs.py --root . --bin build/bin --update)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--root", required=True)
    ap.add_argument("--bin", help="the build's bin/ directory (skip the generated references without it)")
    ap.add_argument("--update", action="store_true")
    a = ap.parse_args()
    a.root = os.path.abspath(a.root)
    problems = []
    if a.bin:
        check_generated(a.root, os.path.abspath(a.bin), a.update, problems)
    check_links(a.root, problems)
    check_section_refs(a.root, problems)
    check_citations(a.root, problems)
    check_user_facing(a.root, problems)
    check_readme_size(a.root, problems)
    for p in problems:
        print(p)
    print(f"{len(md_files(a.root))} pages checked, {len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
