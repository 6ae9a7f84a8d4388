"""Command line: ``python -m isokinetic <command> ...``.

``python -m isokinetic --help`` lists the commands, one line each; ``<command> --help`` explains one:

- ``export-virtual``: write a config's simulated campaign in the raw campaign format;
- ``init-campaign``: draft a folder's ``campaign.yaml`` from its case CSV files, or ``--check`` a folder against
  its manifest (:mod:`isokinetic.init_campaign`);
- ``trace``: audit one number of a results table, re-derived from the raw data (:mod:`isokinetic.audit.trace`);
- ``raw-check``: every raw file a processed campaign read still has its recorded sha256
  (:mod:`isokinetic.audit.raw_check`);
- ``next-test``: the extra cases a campaign's diagnosis proposes (``next_tests`` of diagnosis.json,
  :mod:`isokinetic.diagnosis.plan_text`).

Commands are registered in :func:`build_parser`; each sets ``func(args) -> int``. A command imports
its modules when it runs (function-local imports, on purpose): ``--help`` and each command load
only what they use, not the whole scientific stack.
"""

from __future__ import annotations

import argparse
import inspect
import logging
import os
import sys
from pathlib import Path

import yaml


def _export_virtual(args: argparse.Namespace) -> int:
    """Export a config virtual campaign as a raw campaign folder (raw-campaign-format.md)."""
    from isokinetic.stages.virtual_rig import VirtualCampaign, export_raw_campaign

    config = yaml.safe_load(Path(args.config).read_text(encoding="utf-8")) or {}
    campaigns = config.get("virtual_campaigns") or {}
    if args.campaign not in campaigns:
        raise KeyError(f"{args.config}: virtual_campaigns has no campaign {args.campaign!r}; "
                       f"known: {sorted(campaigns)}")
    vc = VirtualCampaign.from_config(args.campaign, campaigns[args.campaign])
    cases = None if args.cases is None else [c.strip() for c in args.cases.split(",") if c.strip()]
    out = export_raw_campaign(vc, args.out, cases=cases, sample_rate_Hz=args.sample_rate_Hz, name=args.name)
    print(f"wrote {out}")
    return 0


def _init_campaign(args: argparse.Namespace) -> int:
    """Draft FOLDER/campaign.yaml from the folder's case CSV files, or check the folder against its manifest.

    The draft guesses the file format (CSV dialect, encoding, units row, MTS 793 export), each column's role
    and unit (a column in volts is never taken for a scaled one; the roles are checked by physics, and a force
    of the opposite sign is drafted with `invert: true`), the sample rate and each file's waveform (triangle:
    period, amplitude, phase; sine: frequency, amplitude; otherwise free); a stepped record (a sweep,
    standstills) becomes one case per step, each with its time_range_s. Beside every guessed value, a comment
    says how it was found and how sure it is. Case files in subfolders are found; every file passed over is
    listed. The damper block is left for you to fill in. Only FOLDER/campaign.yaml is written, and an
    existing one only with --force.

    --check prints, case by case, where the files disagree with the existing manifest (waveform, period or
    frequency, amplitude, phase, sample rate, units, the column choice and the roles' physics). Exit status:
    0 all agree, 1 otherwise.
    """
    from isokinetic.contracts.settings import project_settings
    from isokinetic.init_campaign.check import print_check
    from isokinetic.init_campaign.draft import write_draft

    settings = project_settings(args.folder)   # the project's config, as ingest and validate apply it
    if args.check:
        return print_check(args.folder, settings=settings)
    path, survey = write_draft(args.folder, force=args.force, settings=settings)
    kinds = survey.case_kinds()
    counts = ", ".join(f"{kinds.count(k)} {k}" for k in ("triangle", "sine", "free", "standstill") if k in kinds)
    print(f"wrote {path}: {len(kinds)} cases ({counts})")
    for f in survey.files:
        if not f.ok:
            print(f"  set aside (commented out): {f.file}: {f.problem}")
    for name, why in survey.skipped:
        print(f"  passed over: {name}: {why}")
    if survey.campaign_note:
        print(f"warning: {survey.campaign_note}", file=sys.stderr)
    print("next: check every 'likely' and 'guess' comment, fill in the damper block, then run "
          f"'python -m isokinetic init-campaign --check {args.folder}'")
    return 0


def _trace(args: argparse.Namespace) -> int:
    """Show how one number of a results table was derived, re-derive it from the raw data and compare.

    Exit status: 0 MATCH, 1 MISMATCH, 2 RAW FILE CHANGED / MISSING FILE / CANNOT TRACE.
    """
    from isokinetic.audit.trace import trace

    logger = logging.getLogger("isokinetic")
    if not logger.handlers:  # the stages' quarantine warnings would otherwise go to stderr raw
        logger.addHandler(logging.NullHandler())
    return trace(args.table, args.selector, root=args.root, config=args.config, rtol=args.rtol).exit_code


def _raw_check(args: argparse.Namespace) -> int:
    """Re-hash every raw file the processed campaigns read and compare with the sha256 recorded at ingest.

    Prints one line per changed or missing file. Exit status: 0 none, 1 any.
    """
    from isokinetic.audit.raw_check import print_changes

    return 1 if print_changes(args.campaign_roots, args.base) else 0


def _next_test(args: argparse.Namespace) -> int:
    """Print the next tests a campaign's diagnosis proposes: the extra cases that would separate what its verdict
    cannot tell apart, with their rig time (results/<campaign>/diagnosis.json, key next_tests; the same cases as a
    manifest fragment: results/<campaign>/next_tests.yaml). One line where no test is needed.
    """
    import json

    from isokinetic.contracts.outputs import STAGE_OUTPUTS
    from isokinetic.diagnosis.plan_text import plan_lines

    path = Path(args.results) / args.campaign / STAGE_OUTPUTS["diagnosis"]["json"]
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no diagnosis of campaign {args.campaign!r} (run the workflow first)")
    print("\n".join(plan_lines(json.loads(path.read_text(encoding="utf-8")).get("next_tests"))))
    return 0


#: One line of help per command (``--help`` lists them).
COMMANDS = {
    "export-virtual": "write a simulated campaign in the raw campaign format",
    "init-campaign": "draft a folder's campaign.yaml from its CSV files; --check a folder against it",
    "trace": "audit one number: its derivation, re-derived from the raw data",
    "raw-check": "check that the raw files a processed campaign read are unchanged",
    "next-test": "the extra cases that would separate what a campaign's diagnosis cannot tell apart",
}


def build_parser() -> argparse.ArgumentParser:
    listing = "\n".join(f"  {name:<16}{text}" for name, text in COMMANDS.items())
    parser = argparse.ArgumentParser(prog="isokinetic", usage="%(prog)s [-h] <command> ...",
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     description="Tools of the isokinetic package.",
                                     epilog=f"commands:\n{listing}\n\n'isokinetic <command> --help' explains one.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="command", help=argparse.SUPPRESS)

    p = sub.add_parser("export-virtual", help=COMMANDS["export-virtual"],
                       description=_export_virtual.__doc__)
    p.add_argument("--config", required=True, help="config YAML with a virtual_campaigns block")
    p.add_argument("--campaign", required=True, help="name of the virtual campaign in the config")
    p.add_argument("--out", required=True,
                   help="campaign folder to create, e.g. data/raw/<name> (must not exist or be empty)")
    p.add_argument("--cases", help="comma-separated case ids, e.g. T04,T12,T22,H01 (default: all)")
    p.add_argument("--sample-rate-Hz", type=float, dest="sample_rate_Hz",
                   help="simulate every selected case at this sample rate")
    p.add_argument("--name", help="campaign id written to campaign.yaml; must equal the --out folder name "
                                  "(default: that folder name)")
    p.set_defaults(func=_export_virtual)

    p = sub.add_parser("init-campaign", help=COMMANDS["init-campaign"],
                       description=inspect.cleandoc(_init_campaign.__doc__),
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       epilog="examples:\n"
                              "  init-campaign data/raw/bench2          draft data/raw/bench2/campaign.yaml\n"
                              "  init-campaign data/raw/bench2 --force  replace an existing draft\n"
                              "  init-campaign data/raw/bench2 --check  compare the files with their manifest")
    p.add_argument("folder", help="campaign folder holding the case CSV files, e.g. data/raw/<campaign>")
    p.add_argument("--force", action="store_true", help="replace an existing campaign.yaml")
    p.add_argument("--check", action="store_true",
                   help="do not draft: check the folder's files against its existing campaign.yaml")
    p.set_defaults(func=_init_campaign)

    p = sub.add_parser("trace", help=COMMANDS["trace"],
                       description=inspect.cleandoc(_trace.__doc__),
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       epilog="examples:\n"
                              "  trace results/paper-lag-damper/characteristic.parquet case=T12,segment=3\n"
                              "  trace results/paper-lag-damper/repeatability.parquet case=T12,direction=-\n"
                              "  trace results/lag-damper-demo/models/models.parquet "
                              "model=surace,direction=+,parameter=D_L\n"
                              "  trace results/paper-lag-damper/characteristic.csv row=0\n"
                              "  trace results/paper-lag-damper/diagnosis.json gap_before\n"
                              "  trace results/blind/scores.parquet scenario=blind-003\n"
                              "  trace results/lag-damper-demo/ingest/timeseries/T12.parquet row=5")
    p.add_argument("table", help="a results table (.parquet, or the CSV exports characteristic.csv and "
                                 "models/models.csv) or diagnosis.json")
    p.add_argument("selector", nargs="?",
                   help="column=value[,column=value...] picking one row, or row=N (0-based); for "
                        "diagnosis.json a key path (gap_before, params.coulomb_force_N, '.' for all keys)")
    p.add_argument("--root", help="project folder the tables' relative paths refer to "
                                  "(default: the folder above results/)")
    p.add_argument("--config", help="config YAML for stage parameters and virtual-rig specs when the files carry "
                                    "no lineage record (default: <root>/config/config.yaml)")
    p.add_argument("--rtol", type=float, help="relative tolerance of the comparison (default 1e-9; 1e-6 for "
                                              "diagnosis.json and blind scores)")
    p.set_defaults(func=_trace)

    p = sub.add_parser("raw-check", help=COMMANDS["raw-check"],
                       description=inspect.cleandoc(_raw_check.__doc__))
    p.add_argument("campaign_roots", nargs="+", help="processed campaign folders, e.g. results/<campaign>")
    p.add_argument("--base", default=".", help="directory the recorded paths are relative to (default: .)")
    p.set_defaults(func=_raw_check)

    p = sub.add_parser("next-test", help=COMMANDS["next-test"], description=inspect.cleandoc(_next_test.__doc__))
    p.add_argument("campaign", help="campaign name (results/<campaign>/diagnosis.json)")
    p.add_argument("--results", default="results", help="the results folder (default: results)")
    p.set_defaults(func=_next_test)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (KeyError, ValueError, FileExistsError, FileNotFoundError) as exc:
        msg = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
        print(f"isokinetic {args.command}: error: {msg}", file=sys.stderr)
        return 1


def run() -> int:
    """:func:`main` for the command line: output piped into a reader that stops early (``| head``) ends
    the command quietly (Python's documented recipe: stdout to devnull, so that the exit's flush is silent)."""
    try:
        code = main()
        sys.stdout.flush()
        return code
    except BrokenPipeError:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1


if __name__ == "__main__":
    sys.exit(run())
