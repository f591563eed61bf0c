"""Ctrl-C interrupts a long batch promptly (KeyboardInterrupt), not at its end."""

import signal
import subprocess
import sys
import textwrap
import time

import pytest

SCRIPT = textwrap.dedent(
    """
    import signal, sys, time
    import numpy as np
    import quadtex

    # A child of a background job starts with SIGINT ignored, and Python
    # then installs no KeyboardInterrupt handler: install it whatever the
    # test runner's own disposition.
    signal.signal(signal.SIGINT, signal.default_int_handler)

    rng = np.random.default_rng(1)
    tex = quadtex.pack(rng.random((256, 256, 3)))
    n = int(sys.argv[1])
    c = rng.random((n, 1, 2))
    quads = np.concatenate([c, c + [0.3, 0], c + [0.3, 0.3], c + [0, 0.3]], axis=1)
    method = sys.argv[2]
    print("ready", flush=True)
    start = time.monotonic()
    try:
        if method == "filter":
            # A tight bound and a large budget: about 0.25 ms a footprint.
            tex.filter(quads, error_bound=1e-6, budget=4096)
        else:
            tex.integrate(np.concatenate([c[:, 0], c[:, 0] + 0.9], axis=1), level=14)
    except KeyboardInterrupt:
        print(f"interrupted after {time.monotonic() - start:.2f}", flush=True)
        sys.exit(3)
    print(f"finished after {time.monotonic() - start:.2f}", flush=True)
    """
)


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT to a child process is POSIX")
@pytest.mark.parametrize("method, n", [("filter", 65536), ("integrate", 1 << 20)])
def test_ctrl_c_interrupts_a_long_batch(method, n):
    child = subprocess.Popen(
        [sys.executable, "-c", SCRIPT, str(n), method],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert child.stdout.readline().strip() == "ready", child.stderr.read()
        time.sleep(0.5)
        sent = time.monotonic()
        child.send_signal(signal.SIGINT)
        out, err = child.communicate(timeout=20)
        waited = time.monotonic() - sent
    finally:
        child.kill()
    assert child.returncode == 3, out + err
    assert out.startswith("interrupted after"), out
    # The batch takes many seconds uninterrupted; Ctrl-C ends it within 1.5 s.
    assert waited < 1.5, f"{method}: {waited:.2f} s after SIGINT"
