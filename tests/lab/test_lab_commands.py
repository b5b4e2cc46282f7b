"""``python -m lab NAME``: the commands, a clear refusal of an unknown one, and the
benchmarks' old names (``python -m bench corpus``, ``bench.train``, ``bench calibrate``)
running the same commands."""

from __future__ import annotations

import pytest

from lab import commands


@pytest.mark.parametrize("argv", [[], ["bogus"], ["--write"]])
def test_an_unknown_command_prints_the_usage(argv: list[str], capsys) -> None:
    assert commands.main(argv) == 2
    err = capsys.readouterr().err
    assert "usage: python -m lab {corpus | train [--write] | decide | calibrate [--write] | " \
        "shape-corpus [--chunks N] | shape [--search | --write]}" in err
    assert all(name in err for name in commands.COMMANDS)


def test_the_old_names_run_the_labs_commands(monkeypatch) -> None:
    import bench.calibrate  # noqa: PLC0415
    import bench.corpus  # noqa: PLC0415
    import bench.train  # noqa: PLC0415

    assert (bench.corpus.corpus, bench.train.train, bench.calibrate.calibrate) == \
        (commands.corpus, commands.train, commands.calibrate)
    ran: list[tuple[str, tuple[str, ...]]] = []
    for name in ("corpus", "train", "calibrate"):
        def run(argv: tuple[str, ...] = (), name: str = name) -> None:
            ran.append((name, tuple(argv)))
        monkeypatch.setattr(getattr(bench, name), name, run)
        monkeypatch.setitem(commands.COMMANDS, name, run)
    bench.corpus.main()
    bench.train.main(["--write"])
    bench.calibrate.main()
    assert commands.main(["train", "--write"]) == 0
    assert ran == [("corpus", ()), ("train", ("--write",)), ("calibrate", ()),
                   ("train", ("--write",))]
