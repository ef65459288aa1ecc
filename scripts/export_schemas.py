#!/usr/bin/env python3
"""Write the JSON Schema of the scenario file format.

The schema is generated from the pydantic models in ``fsreg_ros.core.scenario``,
so it never drifts from what ``load_scenario`` accepts structurally.  (The
meaning checks -- unknown properties, decreasing times, ... -- are beyond JSON
Schema; ``fsreg-sim`` reports those.)  Editors can use it for completion, e.g. with
``# yaml-language-server: $schema=scenario.schema.json`` in a scenario file.

Usage:  scripts/export_schemas.py [OUTPUT]     (default: stdout)

Generated files are build products: do not commit them.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from venv_python import prepare  # noqa: E402

prepare("export_schemas.py")  # .venv, import path

from fsreg_ros.core.scenario import scenario_json_schema  # noqa: E402


def write_message_schemas(scenario_output: str | None) -> None:
    """Write the JSON Schema of every message of :mod:`fsreg_ros.contract` beside the scenario schema.

    One file per topic and per service request/reply, e.g. ``topic.rr.result.schema.json``;
    nothing when the scenario schema goes to stdout.
    """
    from fsreg_ros.contract import json_schemas

    if scenario_output is None or scenario_output == "-":
        return
    directory = Path(scenario_output).parent
    for stem, schema in json_schemas().items():
        text = json.dumps(schema, indent=2, sort_keys=True) + "\n"
        (directory / f"{stem}.schema.json").write_text(text, encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Write the JSON Schema of fsreg scenario files.")
    parser.add_argument("output", nargs="?", help="file to write (default: stdout)")
    args = parser.parse_args(argv)
    text = json.dumps(scenario_json_schema(), indent=2, sort_keys=True) + "\n"
    if args.output is None or args.output == "-":
        sys.stdout.write(text)
        return 0
    try:
        Path(args.output).write_text(text, encoding="utf-8")
        write_message_schemas(args.output)
    except OSError as err:
        print(f"export_schemas: cannot write {args.output}: {err.strerror or err}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
