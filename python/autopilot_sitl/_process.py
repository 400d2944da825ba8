"""A child process of this package: its stdout read on a thread (so it never blocks on a full
pipe) into a log file beside its stderr, the lines scripts read (`autopilot endpoint:`,
`autopilot ready:`, `autopilot summary:`, …) kept, and killed with its parent: every child asks
Linux to end it when the process that started it dies (PR_SET_PDEATHSIG), and every live one is
ended when the interpreter exits, so none outlives a test run."""

import atexit
import ctypes
import os
import signal
import subprocess
import sys
import threading
import time
import weakref
from pathlib import Path

_LIVE = weakref.WeakSet()
_PR_SET_PDEATHSIG = 1


def _die_with_parent():
    """In the child, before exec: SIGKILL when the parent thread's process ends (Linux)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):
        pass


@atexit.register
def _end_all():
    for p in list(_LIVE):
        p.kill()


def live():
    """The processes started and not yet ended."""
    return [p for p in _LIVE if p.running()]


class Child:
    """`args` run with stdout and stderr in `log` (a file), its marked lines kept."""

    def __init__(self, args, log: Path, marks=("autopilot ", "sitl ")):
        self.args = [str(a) for a in args]
        self.log = Path(log)
        self.log.parent.mkdir(parents=True, exist_ok=True)
        self._log_file = open(self.log, "w", buffering=1)
        self._log_file.write("$ " + " ".join(self.args) + "\n")
        self.marks = marks
        self.lines = []
        self._changed = threading.Condition()
        self.proc = subprocess.Popen(
            self.args, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=self._log_file,
            text=True, bufsize=1,
            preexec_fn=_die_with_parent if sys.platform.startswith("linux") else None)
        _LIVE.add(self)
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    @property
    def pid(self) -> int:
        return self.proc.pid

    def _read(self):
        for line in self.proc.stdout:
            self._log_file.write(line)
            if line.startswith(self.marks):
                with self._changed:
                    self.lines.append(line.rstrip("\n"))
                    self._changed.notify_all()
        with self._changed:
            self._changed.notify_all()

    def running(self) -> bool:
        return self.proc.poll() is None

    def wait_line(self, prefix: str, timeout_s: float, count: int = 1):
        """The first `count` kept lines starting with `prefix`, waiting up to `timeout_s`; None
        if the process ended or the time ran out first."""
        end = time.monotonic() + timeout_s
        with self._changed:
            while True:
                found = [line for line in self.lines if line.startswith(prefix)]
                if len(found) >= count:
                    return found[:count]
                left = end - time.monotonic()
                if left <= 0 or (not self._reader.is_alive()):
                    return None
                self._changed.wait(min(left, 0.1))

    def tail(self, chars: int = 3000) -> str:
        """The end of its log."""
        if not self._log_file.closed:
            self._log_file.flush()
        text = self.log.read_text(errors="replace")
        return text[-chars:]

    def interrupt(self, timeout_s: float, sig=signal.SIGINT) -> int:
        """Ctrl-C (or `sig`), as a user ends a run (logs flushed, summary printed); killed if it
        has not ended within `timeout_s`. Its exit status (negative: the signal that ended it)."""
        if self.running():
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self.kill()
        self._finish()
        return self.proc.returncode

    def kill(self):
        """SIGKILL if it still runs."""
        if self.running():
            try:
                os.kill(self.proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        self.proc.wait()
        self._finish()

    def _finish(self):
        self._reader.join(timeout=5)
        if not self._log_file.closed:
            self._log_file.close()
        _LIVE.discard(self)
