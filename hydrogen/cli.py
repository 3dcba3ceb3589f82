"""Command line: ``hydrogen generate``, ``hydrogen simulate``.

Errors that hydrogen raises on purpose are printed as one message (no
traceback) and exit with status 2; ``--check`` exits 1 when generated code is stale.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .errors import HydrogenError

__all__ = ["main"]


def _cmd_generate(args) -> int:
    from .codegen.generate import check, generate
    from .model import load_model
    from .runtime.build import repo_generated_dir

    model = load_model(args.model)
    out = Path(args.out) if args.out else repo_generated_dir() / model.name
    if args.check:
        reasons = check(model, out)
        if reasons:
            print(f"generated code in {out} is stale:", *reasons, sep="\n  ", file=sys.stderr)
            print("run 'hydrogen generate' to regenerate", file=sys.stderr)
            return 1
        print(f"{out}: up to date")
        return 0
    changed = generate(model, out, force=args.force)
    print(f"{out}: {'generated' if changed else 'up to date, nothing regenerated'}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="hydrogen", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    g = sub.add_parser("generate", help="derive the model and write its C into generated/",
                       description="Derive the model symbolically and write C, headers and a manifest.")
    g.add_argument("--model", help="model TOML file (default: the packaged model)")
    g.add_argument("--out", help="output folder (default: generated/<model name> of the checkout)")
    g.add_argument("--check", action="store_true", help="exit 1 if the folder is stale; write nothing")
    g.add_argument("--force", action="store_true", help="regenerate even when up to date")
    g.set_defaults(func=_cmd_generate)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except HydrogenError as exc:
        print(f"hydrogen {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
