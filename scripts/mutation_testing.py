"""Mutation testing of the Python package: the tool behind BENCHMARKS.md's "Mutation testing"
sections. A mutant is the module with one small change; a test run that fails kills it, one
that passes lets it survive (a behaviour no test pins down, or an equivalent change).

    python scripts/mutation_testing.py generate python/spikegs/demo.py MUTANTS/demo
    python scripts/mutation_testing.py cover spikegs/demo.py --out cover.json -- tests/
    python scripts/mutation_testing.py run spikegs/demo.py MUTANTS/demo --out demo.jsonl \\
        --cover cover.json --cap 12 --workers 2
    python scripts/mutation_testing.py run spikegs/demo.py MUTANTS/demo --out demo.jsonl \\
        --ids 0003,0017 -- tests/test_train.py
    python scripts/mutation_testing.py summary demo.jsonl

Mutants (`generate`): each comparison flipped and made strict or loose (`<` -> `>=`, `<=`),
`and` <-> `or`, an `if`'s, `while`'s or conditional expression's test negated, an int constant
+1 and a float x1.1; never inside a `raise`, a warning's call or an f-string (messages).
MUTANTS/NNNN.py each, MUTANTS/index.tsv the id, line and change of each.

The package is run from a staged copy (`--work`, one per worker): the installed package with
the extension it was built with, its Python files replaced by the source tree's (`--sources`,
default python/PACKAGE), so an edited test or module needs no reinstall. `cover` runs the
tests under coverage with a context per test (node id) and keeps, for each line of the given
modules, the tests that ran it, fastest first; `run --cover MAP --cap N` runs each mutant
against the N fastest tests that ran its line ("uncovered" where none did: lines run only at
import or in a child process). A result line: {"id", "line", "what", "status": killed |
survived | timeout | uncovered | no tests | usage error, "seconds", "tail"} ("tail": the end
of pytest's output where the mutant survived). `run` resumes: ids already in OUT are skipped.
"""

from __future__ import annotations

import argparse
import ast
import copy
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

FLIPS = {
    ast.Lt: (ast.GtE, ast.LtE),
    ast.LtE: (ast.Gt, ast.Lt),
    ast.Gt: (ast.LtE, ast.GtE),
    ast.GtE: (ast.Lt, ast.Gt),
    ast.Eq: (ast.NotEq,),
    ast.NotEq: (ast.Eq,),
    ast.Is: (ast.IsNot,),
    ast.IsNot: (ast.Is,),
    ast.In: (ast.NotIn,),
    ast.NotIn: (ast.In,),
}
WARNING_CALLS = {"warn", "warning", "showwarning"}
CONTEXT_PLUGIN = '''
"""Coverage context per test (its node id) and each test's seconds, for mutation_testing.py."""
import json, os, time
import coverage, pytest
seconds = {}
@pytest.hookimpl(tryfirst=True)
def pytest_runtest_protocol(item, nextitem):
    coverage.Coverage.current().switch_context(item.nodeid)
    seconds[item.nodeid] = time.perf_counter()
@pytest.hookimpl(trylast=True)
def pytest_runtest_logfinish(nodeid, location):
    seconds[nodeid] = time.perf_counter() - seconds[nodeid]
def pytest_sessionfinish(session):
    with open(os.environ["MUTATION_SECONDS"], "w") as f:
        json.dump(seconds, f)
'''


def _in_message(node: ast.AST, parents: dict) -> bool:
    """Whether `node` lies in a raise, a warning's call or an f-string."""
    while node is not None:
        if isinstance(node, (ast.Raise, ast.JoinedStr)):
            return True
        if isinstance(node, ast.Call):
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
            if name in WARNING_CALLS:
                return True
        node = parents.get(node)
    return False


def _changes(node: ast.AST) -> list:
    """The mutations of one node: (label, function changing a copy of the node in place)."""
    if isinstance(node, ast.Compare):
        return [
            (
                f"{type(op).__name__}->{new.__name__}",
                lambda n, i=i, new=new: n.ops.__setitem__(i, new()),
            )
            for i, op in enumerate(node.ops)
            for new in FLIPS.get(type(op), ())
        ]
    if isinstance(node, ast.BoolOp):
        swap = ast.Or if isinstance(node.op, ast.And) else ast.And
        return [(f"{type(node.op).__name__}->swap", lambda n: setattr(n, "op", swap()))]
    if isinstance(node, (ast.If, ast.While, ast.IfExp)):
        return [("negate", lambda n: setattr(n, "test", ast.UnaryOp(ast.Not(), n.test)))]
    if isinstance(node, ast.Constant) and type(node.value) in (int, float):
        new = node.value + 1 if isinstance(node.value, int) else node.value * 1.1
        if new != node.value:  # 0.0 and infinities stay
            return [(f"{node.value!r}->{new!r}", lambda n: setattr(n, "value", new))]
    return []


def generate(module: Path, out: Path) -> int:
    """Write every mutant of `module` to OUT/NNNN.py and the list to OUT/index.tsv."""
    tree = ast.parse(module.read_text())
    nodes = list(ast.walk(tree))
    parents = {child: node for node in nodes for child in ast.iter_child_nodes(node)}
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for k, node in enumerate(nodes):
        if _in_message(node, parents):
            continue
        for label, change in _changes(node):
            mutant = copy.deepcopy(tree)
            change(list(ast.walk(mutant))[k])  # ast.walk's order is the same on a copy
            mid = f"{len(rows):04d}"
            (out / f"{mid}.py").write_text(ast.unparse(mutant) + "\n")
            rows.append(f"{mid}\t{node.lineno}\t{label}")
    (out / "index.tsv").write_text("".join(row + "\n" for row in rows))
    return len(rows)


def stage(package: str, sources: Path, dest: Path) -> Path:
    """DEST/PACKAGE: the installed package (its built extension), the source tree's .py files."""
    spec = importlib.util.find_spec(package)
    if spec is None or not spec.submodule_search_locations:
        sys.exit(f"package {package!r} is not importable: install it first (pip install .)")
    target = dest / package
    shutil.rmtree(target, ignore_errors=True)
    shutil.copytree(
        spec.submodule_search_locations[0], target, ignore=shutil.ignore_patterns("__pycache__")
    )
    for path in sources.rglob("*.py"):
        shutil.copy(path, target / path.relative_to(sources))
    return dest.resolve()


def _env(package_dir: Path, **extra) -> dict:
    return {**os.environ, "PYTHONPATH": str(package_dir), "PYTHONDONTWRITEBYTECODE": "1", **extra}


def cover(modules: list, tests: list, package_dir: Path, out: Path) -> None:
    """OUT: {module: {line: [test node ids that ran it, fastest first]}}."""
    with tempfile.TemporaryDirectory() as tmp:
        Path(tmp, "mutation_contexts.py").write_text(CONTEXT_PLUGIN)
        seconds, data = Path(tmp, "seconds.json"), Path(tmp, "coverage")
        env = _env(package_dir, MUTATION_SECONDS=str(seconds), COVERAGE_FILE=str(data))
        env["PYTHONPATH"] += os.pathsep + tmp
        include = ",".join(str(package_dir / m) for m in modules)
        run = [sys.executable, "-m", "coverage", "run", f"--include={include}", "-m", "pytest"]
        plugins = ["-p", "mutation_contexts", "-p", "no:cacheprovider"]
        subprocess.run([*run, "-q", *plugins, *tests], env=env)
        if not seconds.exists():
            sys.exit("cover: pytest ran no session (its error above): no map written")
        report = Path(tmp, "coverage.json")
        to_json = ["json", "--show-contexts", "-o", str(report)]
        subprocess.run([sys.executable, "-m", "coverage", *to_json], env=env, check=True)
        took = json.loads(seconds.read_text())
        files = json.loads(report.read_text())["files"]
    lines = {}
    for name, record in files.items():
        module = Path(name).resolve().relative_to(package_dir.resolve()).as_posix()
        lines[module] = {
            line: sorted({c for c in contexts if c in took}, key=took.get)
            for line, contexts in record["contexts"].items()
        }
    out.write_text(json.dumps(lines, indent=1))


def _pytest(package_dir: Path, tests: list, timeout: float) -> tuple:
    """(status, pytest's output tail) of the tests against the package in `package_dir`."""
    command = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *tests]
    try:
        done = subprocess.run(command, env=_env(package_dir), capture_output=True, text=True,
                              errors="replace", timeout=timeout)  # fmt: skip
    except subprocess.TimeoutExpired:
        return "timeout", ""
    # 1 failed, 2 collection failed (the mutant does not import), 4 pytest's usage, 5 none ran
    status = {0: "survived", 4: "usage error", 5: "no tests"}.get(done.returncode, "killed")
    return status, done.stdout[-400:] if status == "survived" else ""


def run(module: str, mutants: Path, out: Path, tests: list, args) -> None:
    """Each mutant of `module` (relative to the package's parent) against its tests, in parallel."""
    done = set()
    if out.exists():
        done = {json.loads(line)["id"] for line in out.read_text().splitlines() if line.strip()}
    rows = [row.split("\t") for row in (mutants / "index.tsv").read_text().splitlines()]
    rows = [r for r in rows if r[0] not in done and (not args.ids or r[0] in args.ids)]
    lines = json.loads(args.cover.read_text()).get(module, {}) if args.cover else None
    base = stage(args.package, args.sources, args.work / "base")
    free = [
        stage(args.package, args.sources, args.work / f"worker{w}") for w in range(args.workers)
    ]
    lock = threading.Lock()

    def one(row):
        mid, line, what = row
        chosen = tests if lines is None else lines.get(line, [])[: args.cap]
        status, tail, seconds = "uncovered", "", 0.0
        if chosen:
            with lock:
                package_dir = free.pop()
            target = package_dir / module
            target.write_text((mutants / f"{mid}.py").read_text())
            start = time.monotonic()
            try:
                status, tail = _pytest(package_dir, chosen, args.timeout)
            finally:
                shutil.copy(base / module, target)
                seconds = time.monotonic() - start
                with lock:
                    free.append(package_dir)
        result = {"id": mid, "line": int(line), "what": what, "status": status,
                  "seconds": round(seconds, 1), "tail": tail}  # fmt: skip
        with lock, out.open("a") as f:
            f.write(json.dumps(result) + "\n")
        print(mid, line, what, status, flush=True)

    with ThreadPoolExecutor(args.workers) as pool:
        list(pool.map(one, rows))


def summary(paths: list) -> None:
    """Counts of each status and the mutants not killed, per results file."""
    for path in paths:
        results = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
        print(path, dict(Counter(r["status"] for r in results)))
        alive = [f"{r['id']}:{r['line']}:{r['what']}:{r['status']}" for r in results
                 if r["status"] not in ("killed", "timeout")]  # fmt: skip
        print("   ", " ".join(alive) or "none left")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    p = commands.add_parser("generate", help="write a module's mutants")
    p.add_argument("module", type=Path)
    p.add_argument("out", type=Path)
    for name, help in (("cover", "map each line to the tests that run it"),
                       ("run", "run each mutant against its tests")):  # fmt: skip
        p = commands.add_parser(name, help=help)
        modules = "+" if name == "cover" else None
        p.add_argument(
            "module", nargs=modules, help="relative to the package's parent: spikegs/x.py"
        )
        if name == "run":
            p.add_argument("mutants", type=Path, help="the folder `generate` wrote")
            p.add_argument("--cover", type=Path, help="the map `cover` wrote (tests: its lines')")
            p.add_argument("--cap", type=int, default=12, help="fastest covering tests run")
            p.add_argument("--ids", type=lambda s: set(s.split(",")), help="only these mutants")
            p.add_argument("--workers", type=int, default=1)
            p.add_argument("--timeout", type=float, default=300, help="seconds per mutant")
        p.add_argument("--out", type=Path, required=True)
        p.add_argument("--package", default="spikegs")
        p.add_argument("--sources", type=Path, help="default python/PACKAGE")
        p.add_argument("--work", type=Path, default=Path(tempfile.gettempdir(), "mutation-work"))
    p = commands.add_parser("summary", help="count each results file's statuses")
    p.add_argument("results", type=Path, nargs="+")
    argv = sys.argv[1:] if argv is None else argv
    tests = argv[argv.index("--") + 1 :] if "--" in argv else []  # pytest's arguments
    args = parser.parse_args(argv[: len(argv) - len(tests) - ("--" in argv)])
    if args.command == "generate":
        print(generate(args.module, args.out), "mutants in", args.out)
    elif args.command == "summary":
        summary(args.results)
    else:
        args.sources = args.sources or Path("python", args.package)
        if args.command == "cover":
            package_dir = stage(args.package, args.sources, args.work / "cover")
            cover(args.module, tests, package_dir, args.out)
        else:
            if not args.cover and not tests:
                parser.error("run needs pytest's arguments after -- or a --cover map")
            run(args.module, args.mutants, args.out, tests, args)


if __name__ == "__main__":
    main()
