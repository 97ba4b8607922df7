"""`gearsim point`: output, --save, and one-line errors with exit status 2."""

import json
import subprocess
import sys

import pyarrow.parquet as pq

from gearsim.cli import main


def test_point_prints_pattern(capsys):
    assert main(["point", "--omega", "1.05", "--set", "b=1.0", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)
    assert row["label"] == "1/2T" and row["label_npq"] == "2-2-0"
    assert 0 < row["dc"] < 1 and row["lyapunov"] < 0


def test_point_save_writes_series_poincare_and_spectrum(tmp_path, capsys):
    out = tmp_path / "pt.parquet"
    assert main(["point", "-w", "1.05", "--save", str(out)]) == 0
    t = pq.read_table(out).to_pandas()
    assert set(t.kind) == {"time_series", "poincare", "spectrum"}
    spec = t[t.kind == "spectrum"]
    # a 2T motion puts its strongest subharmonic line at w / 2
    sub = spec[(spec.frequency > 0.45 * 1.05) & (spec.frequency < 0.55 * 1.05)].amplitude.max()
    floor = spec[(spec.frequency > 0.3 * 1.05) & (spec.frequency < 0.4 * 1.05)].amplitude.max()
    assert sub > 20 * floor


def test_bad_input_is_one_line_exit_2():
    for args in (["point", "-w", "1", "--set", "xi=-1"], ["point", "-w", "nan"],
                 ["point", "-w", "1", "--set", "bogus=1"], ["point", "-w", "1", "--set", "xi"]):
        r = subprocess.run([sys.executable, "-m", "gearsim", *args], capture_output=True,
                           text=True)
        assert r.returncode == 2, args
        assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr
        assert r.stdout == ""
