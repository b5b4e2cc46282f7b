"""`stiction-gateway` command line: run, check-config, findings, report, opcua-cert, the onboarding
commands import-tags, probe, browse, result-map (:mod:`.runtime.onboarding`), and the
commands other packages register (:data:`COMMANDS`: the simulator's plc-sim and demo).

Exit status: 0 ok, 1 runtime failure (e.g. a port in use), 2 bad usage or bad config (the
problems are printed on stderr, one per line, each naming the file, section and key).
"""

from __future__ import annotations

import argparse
import logging
import sys
from importlib.metadata import entry_points

from .config import Config, load_config
from .config.addresses import describe_assigned
from .errors import ConfigError, GatewayError
from .runtime import onboarding
from .runtime.logs import install_rate_limit
from .runtime.service import run

__all__ = ["COMMANDS", "build_parser", "main"]

COMMANDS = "stiction_gateway.commands"
"""Entry-point group of commands other distributions add (the simulator's ``plc-sim`` and
``demo``, pyproject.toml): a function that adds its subparser, setting ``plugin`` to the
handler. The gateway never imports them by name."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="stiction-gateway",
        description="Edge gateway that finds and sizes sticky control valves.",
    )
    parser.add_argument("--log-level", default="INFO",
                        choices=["DEBUG", "INFO", "WARNING", "ERROR"])
    sub = parser.add_subparsers(dest="command")
    run = sub.add_parser("run", help="run the gateway (until SIGTERM/SIGINT)")
    run.add_argument("--config", required=True, metavar="FILE", help="gateway YAML config")
    check = sub.add_parser("check-config", help="validate a config file without connecting")
    check.add_argument("file", metavar="FILE")
    check.add_argument("--bind-check", action="store_true",
                       help="also try to bind metrics.listen and modbus_server.listen")
    fnd = sub.add_parser("findings", help="the engineer's findings beside the verdicts of "
                         "their day (docs/onboarding.md#9-confirming-a-suspect-valve)")
    fnd.add_argument("--config", required=True, metavar="FILE", help="gateway YAML config")
    rep = sub.add_parser("report", help="the maintenance meeting's page: the valves worst "
                         "first and a section per suspect valve, one HTML file "
                         "(docs/onboarding.md#10-the-list-and-the-report)")
    rep.add_argument("--config", required=True, metavar="FILE", help="gateway YAML config")
    rep.add_argument("--since", default="7d", metavar="PERIOD",
                     help="the period of the verdict history shown: 7d (default), 12h, 2w")
    rep.add_argument("-o", "--output", required=True, metavar="FILE",
                     help="the HTML file to write (- for standard output)")
    rep.add_argument("--sections", type=int, default=25, metavar="N",
                     help="suspect valves given a section of their own (default 25)")
    sub.add_parser("opcua-cert", add_help=False,
                   help="create an OPC UA client (or --server) certificate and key "
                        "(see `stiction-gateway opcua-cert --help`, docs/opcua.md)")
    onboarding.add_commands(sub)
    for entry in sorted(entry_points(group=COMMANDS), key=lambda e: e.name):
        entry.load()(sub)  # e.g. plcsim's plc-sim and demo: they set ``plugin``
    return parser


def _problems(exc: ConfigError) -> int:
    for line in exc.problems:
        print(line, file=sys.stderr)
    return 2


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args, rest = parser.parse_known_args(argv)
    if args.command == "opcua-cert":  # its own parser: pass the remaining arguments on
        from .wire import certs as opcua_cert

        return opcua_cert.main(rest)
    if rest:
        parser.error(f"unrecognized arguments: {' '.join(rest)}")
    if args.command is None:
        parser.print_help()
        return 0
    logging.basicConfig(level=args.log_level,
                        format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    # the sources report every pymodbus failure as a DeviceError, logged once per outage by
    # the poller; pymodbus' own per-attempt lines would repeat it every retry
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    # likewise asyncua: the OPC UA source maps its failures to DeviceError, named from the
    # status codes; asyncua's own ERROR lines (a refused certificate: "Not trusted
    # certificate used" and a traceback, "certificate is no longer valid") would stand
    # beside the poller's line in the journal, or instead of it
    for name in ("asyncua", "asyncuagds"):
        logging.getLogger(name).setLevel(logging.CRITICAL)
    try:
        return _dispatch(args)
    except ConfigError as exc:
        return _problems(exc)
    except (GatewayError, OSError) as exc:
        print(f"stiction-gateway: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130


def _dispatch(args: argparse.Namespace) -> int:
    if args.command == "check-config":
        cfg = load_config(args.file)
        if args.bind_check:
            from .config.checks import bind_check

            problems = bind_check(cfg)
            if problems:
                raise ConfigError(problems)
        print(f"{args.file}: ok ({len(cfg.devices)} device(s), {len(cfg.loops)} loop(s))")
        for line in describe_assigned(cfg):
            print(line)
        _check_findings(cfg)
        return 0
    if args.command == "findings":
        return _findings(args.config)
    if args.command == "report":
        import time

        from .runtime.report import write_report

        n = write_report(load_config(args.config), args.output, since=args.since,
                         now=time.time(), sections=max(0, args.sections))
        if args.output != "-":
            print(f"wrote {args.output}: {n} loop(s) listed")
        return 0
    if args.command in onboarding.COMMANDS:
        return onboarding.dispatch(args)
    if args.command == "run":
        config = load_config(args.config)
        install_rate_limit()  # no flood of events floods the journal (runtime/logs.py)
        return run(config, args.config)
    if getattr(args, "plugin", None) is not None:
        return int(args.plugin(args))
    raise AssertionError(args.command)


def _check_findings(cfg: Config) -> None:
    """check-config's word on the findings file: its problems on stderr, never a failure
    (run skips a bad row and keeps going, and check-config runs before every start)."""
    from .runtime.findings import read_configured

    read = read_configured(cfg)
    if read is None:
        return
    for line in read.problems:
        print(line, file=sys.stderr)
    if not read.readable:
        print(f"{read.source}: not read: run starts without findings (the gateway keeps "
              "running; fix the file and send SIGHUP)", file=sys.stderr)
    else:
        skipped = f", {len(read.problems)} bad row(s) skipped by run" if read.problems else ""
        print(f"{read.source}: {len(read.findings)} finding(s){skipped}")


def _findings(path: str) -> int:
    """``findings``: the agreement table; exit 2 when the file has problems (for a plant's
    CI over its findings file), 0 otherwise."""
    from .config.findings import verdicts_path
    from .core.findings import FindingsBook
    from .outputs.verdicts import read_history
    from .outputs.verdicts.history import HistoryError
    from .runtime.findings import agreement_table, read_configured

    cfg = load_config(path)
    read = read_configured(cfg)
    if read is None:
        raise ConfigError([f"{path}: no 'findings' file in the config (findings: FILE.csv)"])
    book = FindingsBook()
    hist = verdicts_path(cfg.gateway.state_file)
    if not hist.exists():
        note = f"no verdict history yet ({hist}): every verdict unknown"
    else:
        try:
            book.history.load(read_history(hist, max_loops=2 * len(cfg.loops) + 1000))
            note = f"verdict history {hist} ({len(book.history.loops)} loops)"
        except HistoryError as exc:
            note = f"verdict history {hist} unusable ({exc}): every verdict unknown"
    book.apply(read)
    sys.stdout.write(agreement_table(cfg, book, note))
    for line in read.problems:
        print(line, file=sys.stderr)
    return 2 if read.problems else 0


if __name__ == "__main__":
    sys.exit(main())
