"""The command line's example outputs in the manual, as the commands print them today: `slrig eval
--json`, `slrig live --json` and a refused config, run on the default simulated bench in an empty
folder. Prints one JSON object; with --docs rewrites the example blocks of docs/scanning.md.

    python bench/cli_examples.py [--docs]
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import run

REPO = Path(__file__).resolve().parent.parent
BROKEN = """\
cameras:
  - name: camera0
    resolution: [1280, 8]
projectors:
  - name: projector0
    colour: green
"""
COMMANDS = {
    "example-eval": "slrig eval --codec phase --json",
    "example-live": "slrig live --seconds 5 --json",
    "example-bad-config": "slrig scan --config broken.yaml",
}


def measure() -> dict[str, Any]:
    outputs = {}
    with tempfile.TemporaryDirectory() as folder:
        (Path(folder) / "broken.yaml").write_text(BROKEN)
        env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
        for block, command in COMMANDS.items():
            ran = subprocess.run(command.split(), cwd=folder, capture_output=True, text=True, timeout=600, env=env)
            outputs[block] = {"command": command, "exit": ran.returncode, "stdout": ran.stdout, "stderr": ran.stderr}
    return {"benchmark": "cli_examples", "outputs": outputs}


def example(output: dict[str, Any]) -> str:
    text = output["stdout"] or output["stderr"]
    if output["stdout"].lstrip().startswith("{"):  # one JSON object: folded as a reader can follow it
        text = textwrap.fill(json.dumps(json.loads(output["stdout"])), 100, subsequent_indent=" ")
    return f"```\n$ {output['command']}\n{text.rstrip()}\n```"


def main() -> None:
    blocks = {name: (lambda m, name=name: example(m["outputs"][name])) for name in COMMANDS}
    first = next(iter(blocks))
    run(__doc__ or "", first, measure, blocks.pop(first), blocks)


if __name__ == "__main__":
    main()
