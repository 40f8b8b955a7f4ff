"""The tools' tests' one assertion: check(ok, what) records and prints a failure and goes on; finish() prints the
count and exits 1 when anything failed."""
import sys

failures = []


def check(ok, what):
    if not ok:
        failures.append(what)
        print("FAIL:", what)


def finish():
    print(f"{len(failures)} failure(s)" if failures else "ok")
    sys.exit(1 if failures else 0)
