"""The environment the MCX-CL comparisons run in (shared by `compare.py`, `dcs.py` and
`tissue.py`).

MCX-CL's Python module (`pmcxcl`, which bundles an OpenCL ICD loader) and Intel's CPU OpenCL
runtime (`intel-opencl-rt`, `intel-cmplr-lib-rt`) come from PyPI into a virtual environment; a
script calls `reexec_in_venv` first and continues inside the environment, where
`pmcxcl.gpuinfo()` lists the CPU as an OpenCL device. See README.md beside this file.
"""

import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent
PACKAGES = ["pmcxcl", "intel-opencl-rt", "intel-cmplr-lib-rt", "numpy"]
DEFAULT_VENV = REPO / "target" / "mcx-venv"
# Speed of light in mm/s (MCX's length unit is the millimetre).
C_MM_PER_S = 299_792_458_000.0
# The flag a script gets when it runs inside the environment.
IN_VENV = "--in-venv"


def add_run_arguments(p, json: bool = True):
    """The options every comparison script shares: speckle's threads, the first seed, the JSON
    results (`json`), the environment and the binary, either program alone, and the flag of the
    re-run inside the environment."""
    import argparse

    p.add_argument("--threads", type=int, default=0, help="speckle worker threads (0: all cores)")
    p.add_argument("--seed", type=int, default=1, help="first seed of either program")
    if json:
        p.add_argument("--json", type=Path, default=None, help="write the results here")
    p.add_argument("--venv", type=Path, default=DEFAULT_VENV,
                   help="virtual environment for pmcxcl and the OpenCL runtime")
    p.add_argument("--speckle", type=Path, default=None,
                   help="the speckle binary (default: build <target>/ci/speckle with cargo)")
    p.add_argument("--skip-mcx", action="store_true", help="only run speckle")
    p.add_argument("--skip-speckle", action="store_true", help="only run MCX-CL")
    p.add_argument(IN_VENV, action="store_true", help=argparse.SUPPRESS)


def speckle_render(exe, command: str, scene, out, seed: int, paths: int, threads: int = 0,
                   cwd=None):
    """Runs `speckle <command> <scene>` quietly into `out` with `seed` and `paths` (and
    `threads` when not 0); returns the sidecar JSON (`<name>.<command>.json`, the one file in
    `out` ending so) and the process's wall time. A failure ends the script with its message."""
    import json
    import time

    cmd = [str(exe), command, str(scene), "--quiet", "--no-png", "--out", str(out),
           "--seed", str(seed), "--paths", str(paths)]
    if threads:
        cmd += ["--threads", str(threads)]
    t = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, cwd=cwd)
    wall = time.perf_counter() - t
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{done.stderr}")
    sidecars = sorted(Path(out).glob(f"*.{command}.json"))
    if len(sidecars) != 1:
        raise SystemExit(f"{' '.join(cmd)} wrote {len(sidecars)} sidecars")
    return json.loads(sidecars[0].read_text()), wall


def venv_python(venv: Path) -> Path:
    return venv / "bin" / "python"


def ensure_venv(venv: Path):
    """Creates the environment and installs the packages (once)."""
    py = venv_python(venv)
    if not py.exists():
        print(f"creating {venv}", file=sys.stderr)
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    probe = subprocess.run([str(py), "-c", "import pmcxcl, numpy"], capture_output=True)
    if probe.returncode != 0:
        print(f"installing {' '.join(PACKAGES)} into {venv}", file=sys.stderr)
        subprocess.run([str(py), "-m", "pip", "install", "-q", *PACKAGES], check=True)


def opencl_env(venv: Path) -> dict:
    """The environment under which the ICD loader bundled with pmcxcl finds Intel's CPU runtime.

    The ICD file that `intel-opencl-rt` ships names a build-time path
    (/opt/anaconda1anaconda2anaconda3/lib/libintelocl.so), so a vendors directory is written
    here that names the library inside the environment; its own libraries (TBB and the
    compiler runtime) are found through LD_LIBRARY_PATH.
    """
    lib = venv / "lib"
    so = lib / "libintelocl.so"
    if not so.exists():
        candidates = sorted(lib.glob("libintelocl.so*"))
        if not candidates:
            raise SystemExit(f"no libintelocl.so in {lib}: is intel-opencl-rt installed?")
        so = candidates[0]
    icd = venv / "icd"
    icd.mkdir(exist_ok=True)
    (icd / "intel-cpu.icd").write_text(f"{so}\n")
    env = dict(os.environ)
    env["OCL_ICD_VENDORS"] = str(icd)
    env["LD_LIBRARY_PATH"] = f"{lib}:{env.get('LD_LIBRARY_PATH', '')}".rstrip(":")
    return env


def reexec_in_venv(script: str, venv: Path, argv: list):
    """Sets up the environment and runs `script` again inside it with `argv` and `IN_VENV`;
    exits with its status. Call it first unless `IN_VENV` is in `argv`."""
    ensure_venv(venv)
    env = opencl_env(venv)
    cmd = [str(venv_python(venv)), str(Path(script).resolve()), IN_VENV, *argv]
    sys.exit(subprocess.run(cmd, env=env).returncode)


def speckle_binary(given, profile: str):
    """`given`, or `<target>/<profile>/speckle` built with
    `cargo build --profile <profile> -p speckle-cli` (`<target>`: `CARGO_TARGET_DIR` or the
    workspace's `target`)."""
    if given is not None:
        return Path(given)
    cmd = ["cargo", "build", "--profile", profile, "-p", "speckle-cli"]
    subprocess.run(cmd, cwd=REPO, check=True)
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    return target / profile / "speckle"
