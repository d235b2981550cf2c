"""Layering: everything that does not move grains runs without YADE; the YADE bootstrap fails clearly."""

import subprocess
import sys


def test_flow_case_runs_without_importing_yade(tmp_path):
    code = (
        "import sys\n"
        "from hmdem.hele_shaw import main\n"
        f"assert main(['linear', '--case', 'chen', '--quiet', '--out', r'{tmp_path / 'run'}']) == 0\n"
        "assert not any(m == 'yade' or m.startswith('yade.') for m in sys.modules), 'YADE was imported'\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_missing_yade_gives_one_clear_error():
    code = (
        "import hmdem.yade_env as y\n"
        "y.KNOWN_PREFIXES = ()\n"
        "y.glob.glob = lambda pattern: []\n"
        "try:\n"
        "    y.import_yade()\n"
        "except y.YadeNotFound as exc:\n"
        "    print(exc)\n"
        "else:\n"
        "    raise SystemExit('no error')\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={"PATH": "/usr/bin:/bin", "HMDEM_YADE_PATH": "/nonexistent"})
    assert proc.returncode == 0, proc.stderr
    assert "make setup" in proc.stdout and "HMDEM_YADE_PATH" in proc.stdout
