"""Renders release the GIL (another Python thread runs meanwhile) and honour ctrl-c (SIGINT
raises KeyboardInterrupt within a second on an idle machine, and the process is still usable). Run time: about 5 s."""

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time

import speckle


def test_the_gil_is_released_during_a_render():
    scene = speckle.Scene.example("default", paths=300_000)
    ticks = 0
    done = threading.Event()

    def count():
        nonlocal ticks
        while not done.is_set():
            ticks += 1
            time.sleep(0.001)

    t = threading.Thread(target=count)
    t.start()
    start = time.perf_counter()
    speckle.intensity(scene)
    wall = time.perf_counter() - start
    done.set()
    t.join()
    # The counter thread runs about once a millisecond while the render holds no GIL.
    assert wall > 0.2, wall
    assert ticks > 0.2 * wall * 1000, (ticks, wall)


def test_ctrl_c_interrupts_a_render():
    # A child of a process that ignores SIGINT (a background job of a non-interactive shell)
    # ignores it too, since Python leaves an ignored SIGINT alone: say so instead of waiting.
    assert signal.getsignal(signal.SIGINT) is not signal.SIG_IGN, (
        "SIGINT is ignored in this process (run the tests in the foreground)"
    )
    code = textwrap.dedent(
        """
        import sys, time, speckle
        scene = speckle.Scene.example("default", paths=10**10)
        print("rendering", flush=True)
        try:
            speckle.covariance(scene, force=True)  # days of work: past the resource guard
        except KeyboardInterrupt:
            t = time.perf_counter()
            print("interrupted", flush=True)
            # The interpreter is still usable: a small render runs.
            r = speckle.intensity(scene.with_settings(paths=2000))
            print("after", r.intensity.shape, flush=True)
            sys.exit(3)
        """
    )
    p = subprocess.Popen(
        [sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    # A child that never reacts (SIGINT ignored, as in a background job of a non-interactive
    # shell, which Python then leaves ignored) is killed after a minute, so the test fails
    # instead of hanging.
    watchdog = threading.Timer(60.0, p.kill)
    watchdog.start()
    assert p.stdout.readline().strip() == "rendering"
    time.sleep(1.5)
    sent = time.perf_counter()
    p.send_signal(signal.SIGINT)
    line = p.stdout.readline().strip()
    waited = time.perf_counter() - sent
    out, err = p.communicate(timeout=60)
    watchdog.cancel()
    assert line == "interrupted", (line, out, err)
    assert p.returncode == 3, (out, err)
    assert "after (2, 256)" in out, (out, err)
    # Within milliseconds on an idle machine; a generous bound for a loaded one.
    assert waited < 5.0, waited


def test_thread_counts_beyond_the_machine_are_refused_before_rendering():
    # Issue 27, item 6: threads=65535 started 65 535 OS threads.
    import pytest

    scene = speckle.Scene.example("default", paths=10**9)
    for threads in (0, 65535):
        start = time.perf_counter()
        with pytest.raises(ValueError, match=rf"threads: must lie in 1\.\.=\d+ .*\(got {threads}\)") as e:
            speckle.intensity(scene, threads=threads)
        assert e.value.field == "threads"
        assert time.perf_counter() - start < 5
    assert speckle.intensity(speckle.Scene.example("default", paths=1000), threads=2).intensity.size > 0
