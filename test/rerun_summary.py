"""pytest plugin (loaded by test/conftest.py): every run ends with the count of automatic reruns.

A rerun that passed hides a race the way a retry loop does; the summary line keeps it visible, names each rerun
test and the first line of its first failure.
"""


def pytest_terminal_summary(terminalreporter):
    """One line with the count of automatic reruns at the end of every run, then each rerun test and why it failed
    the first time: a rerun that passed must not hide a race."""
    reruns = terminalreporter.stats.get("rerun", [])
    terminalreporter.write_sep("=", f"reruns: {len(reruns)}", bold=True, red=bool(reruns), green=not reruns)
    for report in reruns:
        crash = getattr(report.longrepr, "reprcrash", None)
        why = crash.message if crash is not None else str(report.longrepr)
        first = next((line for line in why.splitlines() if line.strip()), "")
        terminalreporter.write_line(f"RERUN {report.nodeid} ({report.when}): {first[:200]}")
