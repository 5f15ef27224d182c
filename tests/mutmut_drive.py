"""Run the mutmut mutants of one module through mutmut's trampolines with a chosen test selection.

Run it from a mutmut work copy (the directory holding the `mutants/` tree that `mutmut run`
generates; see tests/MUTANTS.md for the set-up), with MUTANTS_DIR pointing there.
Collect once in the parent (no compiled-core calls there: checked by the thread count), then fork
children that run pytest's default run loop:
  1. a baseline child with MUTANT_UNDER_TEST=stats (unmutated; must exit 0) that records, per test,
     which mutated functions it calls (setup of module/session-scoped fixtures is attributed to every
     test using the fixture);
  2. one child per mutant, MUTANT_UNDER_TEST=<key>, running (-x) only the selected tests that call
     the mutated function ("no tests" if none does).
Results in $MUTMUT_OUT/mutmut_drive_<module>.json (default /tmp): key -> [exit code | "timeout" | "no tests", seconds].
usage: MUTANTS_DIR=<work copy> python tests/mutmut_drive.py MODULE TIMEOUT_S [KEYS_FILE|-] -- pytest args..."""

import json
import os
import signal
import sys
import time

i = sys.argv.index("--")
module, timeout = sys.argv[1], float(sys.argv[2])
keys_file = sys.argv[3] if i > 3 else "-"
tests = sys.argv[i + 1 :]
ROOT = os.path.abspath(os.path.join(os.environ.get("MUTANTS_DIR", "."), "mutants"))
OUT = os.environ.get("MUTMUT_OUT", "/tmp")
os.chdir(ROOT)
sys.path[:0] = [f"{ROOT}/src", f"{ROOT}/tests", ROOT]
os.environ["MUTANT_UNDER_TEST"] = ""
import pytest, _pytest.main  # noqa
import mutmut.mutation.trampoline as T  # noqa: E402 (after MUTANT_UNDER_TEST is set)

meta = json.load(open(f"src/fakeack/{module}.py.meta"))
keys = list(meta["exit_code_by_key"])
if keys_file != "-":
    keys = [k for k in open(keys_file).read().split() if k]
SUF = os.environ.get("OUT_SUFFIX", "")
out_path = f"{OUT}/mutmut_drive_{module}{SUF}.json"
hits_path = f"{OUT}/mutmut_hits_{module}{SUF}.json"
res = json.load(open(out_path)) if os.path.exists(out_path) else {}
log = open(f"{OUT}/mutmut_drive_{module}{SUF}.log", "a")


def say(s):
    print(s, flush=True)
    log.write(s + "\n")
    log.flush()


# --- stats recording (only active in the stats child) ---
cur = {"test": None, "fix": []}
test_hits, fix_hits, dur = {}, {}, {}


def record(name, caller=None):
    if cur["test"] is not None:
        test_hits.setdefault(cur["test"], set()).add(name)
    for f in cur["fix"]:
        fix_hits.setdefault(f, set()).add(name)


T.record_trampoline_hit = record


class Recorder:
    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_protocol(self, item, nextitem):
        cur["test"] = item.nodeid
        yield
        cur["test"] = None

    @pytest.hookimpl(hookwrapper=True)
    def pytest_fixture_setup(self, fixturedef, request):
        k = f"{fixturedef.baseid}::{fixturedef.argname}"
        cur["fix"].append(k)
        yield
        cur["fix"].pop()

    def pytest_runtest_logreport(self, report):
        dur[report.nodeid] = dur.get(report.nodeid, 0.0) + report.duration


def run_child(session, key, items, stats=False, limit=None):
    s = time.time()
    limit = timeout if limit is None else limit
    pid = os.fork()
    if pid == 0:
        try:
            os.environ["MUTANT_UNDER_TEST"] = key
            T.set_mutant_under_test(key)
            fd = os.open("/dev/null", os.O_WRONLY)
            os.dup2(fd, 1)
            os.dup2(fd, 2)
            session.items = items
            if stats:
                session.config.pluginmanager.register(Recorder())
            _pytest.main.pytest_runtestloop(session)
            rc = 1 if session.testsfailed else 0
        except BaseException:  # -x raises session.Interrupted after the first failure
            rc = 1 if session.testsfailed else 3
        if stats:
            out = {}
            for it in items:
                h = set(test_hits.get(it.nodeid, ()))
                for _name, fds in it._fixtureinfo.name2fixturedefs.items():
                    for fdf in fds:
                        if fdf.scope != "function":
                            h |= fix_hits.get(f"{fdf.baseid}::{fdf.argname}", set())
                out[it.nodeid] = sorted(h)
            json.dump({"hits": out, "dur": dur}, open(hits_path, "w"))
        os._exit(rc)
    while True:
        p, st = os.waitpid(pid, os.WNOHANG)
        if p:
            rc = os.waitstatus_to_exitcode(st)
            break
        if time.time() > s + (limit if not stats else 2 * float(os.environ.get("MAX_BASELINE", "45"))):
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            rc = "timeout"
            break
        time.sleep(0.02)
    return rc, time.time() - s


class Driver:
    @pytest.hookimpl(tryfirst=True)
    def pytest_runtestloop(self, session):
        nthreads = len(os.listdir("/proc/self/task"))
        say(
            f"[{module}] collected {len(session.items)} tests, parent threads={nthreads}, "
            f"mutants={len(keys)}, done before={sum(k in res for k in keys)}"
        )
        if nthreads != 1:
            say("ABORT: parent has extra threads (compiled core called at collection?)")
            os._exit(5)
        items = list(session.items)
        rc, dt = run_child(session, "stats", items, stats=True)
        say(f"[{module}] baseline (stats) rc={rc} {dt:.1f}s")
        if rc != 0:
            os._exit(6)
        if dt > float(os.environ.get("MAX_BASELINE", "45")):
            say(f"[{module}] baseline over MAX_BASELINE, stop")
            os._exit(7)
        hd = json.load(open(hits_path))
        hits, tdur = hd["hits"], hd["dur"]
        slow = sorted(tdur.items(), key=lambda x: -x[1])[:5]
        say(f"[{module}] slowest tests: " + ", ".join(f"{n} {d:.1f}s" for n, d in slow))
        # each mutant runs the tests calling its function, fastest first (-x stops at the first failure)
        items.sort(key=lambda it: tdur.get(it.nodeid, 0.0))
        t0 = time.time()
        for k in keys:
            if k in res:
                continue
            func = k.partition("__mutmut_")[0]
            sel = [it for it in items if func in hits.get(it.nodeid, ())]
            if os.environ.get("FULL"):
                sel = items
            if not sel:
                res[k] = ["no tests", 0.0]
                rc, dt = "no tests", 0.0
            else:
                # per-mutant limit: 5x the covering tests' unmutated time + 5 s, at least 15 s, at most TIMEOUT_S
                est = sum(tdur.get(it.nodeid, 0.0) for it in sel)
                rc, dt = run_child(session, k, sel, limit=min(timeout, max(15.0, 5 * est + 5)))
                res[k] = [rc, round(dt, 2)]
            json.dump(res, open(out_path, "w"))
            log.write(f"{k} {rc} {dt:.1f}s {len(sel)}\n")
            log.flush()

        def c(f):
            return sum(1 for k in keys if k in res and f(res[k][0]))

        say(
            f"[{module}] done {sum(k in res for k in keys)}/{len(keys)} in {time.time() - t0:.0f}s: "
            f"killed={c(lambda r: r not in (0, 'timeout', 'no tests'))} survived={c(lambda r: r == 0)} "
            f"no_tests={c(lambda r: r == 'no tests')} timeout={c(lambda r: r == 'timeout')}"
        )
        return True


sys.exit(
    pytest.main(
        ["-x", "-q", "--tb=no", "-p", "no:cacheprovider", "-p", "no:randomly", *tests], plugins=[Driver()]
    )
)
