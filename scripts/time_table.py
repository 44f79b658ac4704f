#!/usr/bin/env python3
"""The time table scripts/test.sh prints at its end: its steps' wall times, each test
binary's total, and the slowest tests (from cargo-nextest's JUnit report), so that CI's log
shows where the next regression went.

    scripts/time_table.py STEPS.tsv [JUNIT.xml] [--slowest 20]
STEPS.tsv: lines "name<TAB>seconds" (written by scripts/test.sh)."""
import sys
import xml.etree.ElementTree as ET


def main(argv):
    slowest = 20
    if "--slowest" in argv:
        i = argv.index("--slowest")
        slowest = int(argv[i + 1])
        del argv[i : i + 2]
    steps_path = argv[1]
    junit_path = argv[2] if len(argv) > 2 else None
    steps = []
    with open(steps_path) as f:
        for line in f:
            name, _, secs = line.rstrip("\n").rpartition("\t")
            if name:
                steps.append((name, float(secs)))
    total = sum(s for _, s in steps)
    print("\n== time table ==")
    print(f"{'step':58} {'wall s':>8}")
    for name, secs in steps:
        print(f"{name:58} {secs:8.1f}")
    print(f"{'total':58} {total:8.1f}  ({total / 60:.1f} min)")
    if not junit_path:
        return
    try:
        root = ET.parse(junit_path).getroot()
    except (OSError, ET.ParseError) as e:
        print(f"(no test report: {e})")
        return
    binaries, tests = {}, []
    for suite in root.iter("testsuite"):
        name = suite.get("name", "?")
        for case in suite.iter("testcase"):
            t = float(case.get("time", "0") or 0)
            n, s = binaries.get(name, (0, 0.0))
            binaries[name] = (n + 1, s + t)
            tests.append((t, f"{name} {case.get('name', '?')}"))
    print(f"\n{'test binary':58} {'tests':>6} {'sum of test s':>14}")
    for name, (n, s) in sorted(binaries.items(), key=lambda kv: -kv[1][1]):
        print(f"{name:58} {n:6} {s:14.1f}")
    print(f"\nthe {slowest} slowest tests (wall s of each, two tests running at once):")
    for t, name in sorted(tests, reverse=True)[:slowest]:
        print(f"{t:8.1f}  {name}")


if __name__ == "__main__":
    main(sys.argv)
