"""`python -m benchmarks.peak CMD [ARGS...]`: run CMD as this small process' child, then print
`PEAK_KIB n`, the child's peak resident memory (KiB, from the kernel's rusage of it).

Why a launcher: Linux keeps a process' memory high-water mark across exec (the larger of the old
and the new image's), and a child forked from the benchmark's own process starts with that
process' image, so measured directly its peak could never show less than the benchmark itself
(which holds torch, a served app, ...). This launcher imports nothing but the standard library, so
the command's figure is its own (floor: this interpreter, about 10 MiB). Ctrl-C (SIGINT) is passed
on to the command; the launcher exits with the command's status. The caller starts it in a session
of its own, so that a kill of the group reaches the command too. resident_mib reads a process'
own figures where it cannot be launched so (a Dask worker, the served app).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path


def resident_mib(field: str = "VmRSS") -> float:
    """This process' resident memory (MiB) from /proc/self/status: VmRSS now, VmHWM its peak (NaN
    where there is none). VmHWM is this image's own: rusage's ru_maxrss is not, in a process
    started from a larger one (multiprocessing's spawn, as Dask's workers are: fork, then exec)."""
    status = Path("/proc/self/status")
    for line in status.read_text().splitlines() if status.exists() else []:
        if line.startswith(field + ":"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def main(argv: list[str]) -> int:
    # stdout and stderr inherited: the command's lines go straight through. Its Ctrl-C restored: a
    # job started in the background of a shell has SIGINT ignored, and that would be inherited.
    child = subprocess.Popen(argv, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    signal.signal(signal.SIGINT, lambda *_: child.send_signal(signal.SIGINT))
    _, status, usage = os.wait4(child.pid, 0)
    print(f"PEAK_KIB {usage.ru_maxrss}", flush=True)
    return os.waitstatus_to_exitcode(status)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
