#!/usr/bin/env python3
"""Did the last ctest run fail only through LeakSanitizer's own tracer crashing?

LeakSanitizer stops the world at process exit with a ptrace-based tracer thread; that tracer
sometimes takes a SIGSEGV itself ("Tracer caught signal 11" ... "LeakSanitizer has encountered a
fatal error"), after a test's body has passed, with no leak report. It is a known intermittent
failure of the sanitizer runtime (google/sanitizers#1353), not a finding. CI hit it once in
vio/loop_closure (2026-12-03: 7 of 7 tests passed, then the tracer crashed).

Reads BUILD/Testing/Temporary/LastTest.log and LastTestsFailed.log. Exit 0 when every failed
test's output holds the tracer's fatal error, so that scripts/test.sh --sanitize reruns exactly
those tests once; exit 1 (naming the failures) otherwise, or when a test failed without the
signature. A real sanitizer report (a leak, an ASan or UBSan error) is not the tracer's crash:
such a test is not retried.

  tracer_crash_only.py BUILD_DIR
  tracer_crash_only.py --self-test   plants ctest logs and checks each verdict
"""
import pathlib
import re
import sys
import tempfile

TRACER = "LeakSanitizer has encountered a fatal error"
# A sanitizer report or a failed GoogleTest assertion: a real failure, never retried.
REPORTS = ("ERROR: AddressSanitizer", "ERROR: LeakSanitizer: detected memory leaks", "runtime error:",
           "[  FAILED  ]")


def outputs(log_text):
    """Test name -> its output, from ctest's LastTest.log."""
    result = {}
    pattern = re.compile(r'^\d+/\d+ Test: (.+?)\n.*?^Output:\n-+\n(.*?)^<end of output>', re.M | re.S)
    for match in pattern.finditer(log_text):
        result[match.group(1)] = match.group(2)
    return result


def verdict_for(build_dir):
    temporary = pathlib.Path(build_dir) / "Testing" / "Temporary"
    failed_path = temporary / "LastTestsFailed.log"
    log_path = temporary / "LastTest.log"
    if not failed_path.is_file() or not log_path.is_file():
        print(f"tracer_crash_only: no {failed_path} or {log_path}", file=sys.stderr)
        return 1
    failed = [line.split(":", 1)[1].strip() for line in failed_path.read_text().splitlines() if ":" in line]
    if not failed:
        print(f"tracer_crash_only: {failed_path} names no test", file=sys.stderr)
        return 1
    texts = outputs(log_path.read_text(errors="replace"))
    verdict = 0
    for name in failed:
        text = texts.get(name)
        if text is None:
            print(f"tracer_crash_only: {name}: no output in {log_path}")
            verdict = 1
        elif TRACER not in text:
            print(f"tracer_crash_only: {name} failed on its own (no LeakSanitizer tracer crash)")
            verdict = 1
        elif any(report in text for report in REPORTS):
            print(f"tracer_crash_only: {name} has a sanitizer report or a failed assertion beside the tracer crash")
            verdict = 1
        else:
            print(f"tracer_crash_only: {name}: LeakSanitizer's tracer crashed at exit (no report)")
    return verdict


def entry(number, name, output, passed):
    return (f"----------------------------------------------------------\n{number}/9 Testing: {name}\n"
            f"{number}/9 Test: {name}\nCommand: \"/x/{name}\"\nDirectory: /x\n"
            f"\"{name}\" start time: Dec 03 16:50 UTC\nOutput:\n"
            f"----------------------------------------------------------\n{output}<end of output>\n"
            f"Test time =   1.00 sec\n----------------------------------------------------------\n"
            f"Test {'Passed' if passed else 'Failed'}.\n")


def self_test():
    """Each planted log with the verdict it must get (0 = rerun, 1 = a real failure)."""
    crash = ("[  PASSED  ] 7 tests.\nTracer caught signal 11: addr=0x22cb8 pc=0x7f36a4ae80f0\n"
             "==31287==LeakSanitizer has encountered a fatal error.\n")
    leak = "==1==ERROR: LeakSanitizer: detected memory leaks\n" + crash
    failed = "[  FAILED  ] LoopClosure.SquareFlightClosesItsLoop\n" + crash
    cases = [
        ("the tracer crash alone", [("a/one", crash, False), ("a/two", "ok\n", True)], 0),
        ("two tests, both the tracer", [("a/one", crash, False), ("a/two", crash, False)], 0),
        ("a test failed without the tracer", [("a/one", crash, False), ("a/two", "boom\n", False)], 1),
        ("a leak report", [("a/one", leak, False)], 1),
        ("a failed assertion", [("a/one", failed, False)], 1),
        ("an ASan error", [("a/one", "==1==ERROR: AddressSanitizer: heap-use-after-free\n" + crash, False)], 1),
        ("a UBSan error", [("a/one", "x.cc:3:5: runtime error: signed integer overflow\n" + crash, False)], 1),
    ]
    bad = 0
    for title, tests, expected in cases:
        with tempfile.TemporaryDirectory() as build:
            temporary = pathlib.Path(build) / "Testing" / "Temporary"
            temporary.mkdir(parents=True)
            log = "Start testing: Dec 03 16:50 UTC\n" + "".join(
                entry(i + 1, name, output, passed) for i, (name, output, passed) in enumerate(tests))
            (temporary / "LastTest.log").write_text(log)
            (temporary / "LastTestsFailed.log").write_text(
                "".join(f"{i + 1}:{name}\n" for i, (name, _, passed) in enumerate(tests) if not passed))
            got = verdict_for(build)
        if got != expected:
            print(f"self-test FAILED: {title}: verdict {got}, expected {expected}")
            bad += 1
    if bad == 0:
        print(f"self-test passed: {len(cases)} planted logs, each verdict right")
    return 1 if bad else 0


def main():
    if sys.argv[1:] == ["--self-test"]:
        return self_test()
    if len(sys.argv) != 2:
        print(__doc__.strip().splitlines()[-2].strip(), file=sys.stderr)
        return 2
    return verdict_for(sys.argv[1])


if __name__ == "__main__":
    sys.exit(main())
