"""A bad command line's check, shared by the reconstruct tests: one line, exit status 1, nothing written."""

from catadioptric.cli import main


def one_line_error(capsys, folder, argv, message):
    """`catadioptric ARGV` exits 1 with one line on stderr holding `message`, no traceback, and `folder` as it was."""
    before = sorted(p.name for p in folder.iterdir())
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 1, err
    assert err.count("\n") == 1 and "Traceback" not in err and message in err, err
    assert sorted(p.name for p in folder.iterdir()) == before
