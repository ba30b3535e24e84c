#!/usr/bin/python3
"""Test: runs the command blocks of docs/tutorial.md marked `<!-- test -->`, in order, in a fresh
folder, with the build's programs on PATH; fails on the first command that fails.

    run_tutorial.py SOURCE_DIR BUILD_DIR WORK_DIR

A block marked `<!-- test: needs PROGRAM -->` is skipped (and said so) when PROGRAM is not here.
"""
import os
import re
import shutil
import subprocess
import sys

source, build, work = (os.path.abspath(a) for a in sys.argv[1:4])
text = open(os.path.join(source, "docs", "tutorial.md")).read()
blocks = re.findall(r"<!-- test(?:: needs (\S+))? -->\s*```sh\n(.*?)```", text, re.S)
assert len(blocks) >= 5, f"expected the tutorial's test blocks, found {len(blocks)}"

shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
env = dict(os.environ)
env["PATH"] = os.pathsep.join([os.path.join(build, "src", "builder"),
                               os.path.join(build, "examples"),
                               os.path.join(build, "examples", "viewer"), env.get("PATH", "")])
env["PYTHONPATH"] = os.path.join(build, "python")
env["FSM_SOURCE_DIR"] = source
env["FSM_CACHE_DIR"] = os.path.join(work, "cache")
env.pop("WAYLAND_DISPLAY", None)
for k, (needs, script) in enumerate(blocks, 1):
    if needs and shutil.which(needs) is None:
        print(f"--- block {k}: skipped ({needs} is not installed)")
        continue
    print(f"--- block {k}:\n{script.rstrip()}")
    run = subprocess.run(["bash", "-euo", "pipefail", "-c", script], cwd=work, env=env,
                         timeout=600)
    if run.returncode != 0:
        sys.exit(f"tutorial block {k} failed with exit status {run.returncode}")
print(f"ok: {len(blocks)} tutorial blocks")
