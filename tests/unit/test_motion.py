"""The three motion classes (cell.motion) against the impact counts the classifier records, and
the paper's facts (analysis.paper) against what the paper's text says of them."""

import re

import numpy as np
import pandas as pd

from gearsim.analysis import paper
from gearsim.cell.classify import impact_state
from gearsim.cell.motion import double_sided, face_impact, no_impact


def test_classes_partition_the_impact_states():
    # every (face, back) count pair the classifier can see, in contact part of the time
    for face in (0, 1, 3):
        for back in (0, 1, 2):
            I = impact_state(face, back, 0.3, 1.0)
            classes = [bool(double_sided(I, back)), bool(face_impact(I)), bool(no_impact(I))]
            assert sum(classes) == 1, (face, back, I)
            assert classes[0] == (back > 0)
            assert classes[1] == (face > 0 and back == 0)
            assert classes[2] == (face == 0 and back == 0)
    never = impact_state(0, 0, 1.0, 1.0)  # never in contact: in none of the classes
    assert not (double_sided(never) or face_impact(never) or no_impact(never))


def test_double_sided_on_tables():
    cells = pd.DataFrame({"I": [0, 1, 2, -1, 1, -2], "q": [0, 0, 1, 2, np.nan, 0]},
                         index=[10, 11, 12, 13, 14, 15])
    out = double_sided(cells["I"], cells["q"])
    assert isinstance(out, pd.Series) and list(out.index) == list(cells.index)
    assert out.tolist() == [False, False, True, True, False, False]
    # a chaotic cell has no per-period count: its I alone decides
    assert double_sided(np.array([2, 1]), np.array([np.nan, np.nan])).tolist() == [True, False]
    assert double_sided(cells["I"]).tolist() == out.tolist()


def test_paper_facts_are_consistent():
    ws = [pl.w for pl in paper.PAPER_LANDMARKS]
    assert ws == sorted(ws) and len(ws) == 12  # the table of Sect 3.1, in sweep order
    assert all(pl.w_range[0] <= pl.w <= pl.w_range[1] for pl in paper.PAPER_LANDMARKS)
    assert abs(paper.PAPER_GAP - (0.66 - 0.569)) < 1e-12
    assert set(paper.PAPER_SEQUENCES) <= set(paper.PAPER_SWEEPS) == set(paper.PAPER_SEQUENCE_TEXT)
    for key, seq in paper.PAPER_SEQUENCES.items():
        # the paper's words name the same patterns in the same order
        words = paper.PAPER_SEQUENCE_TEXT[key].split(" (Fig")[0]
        tokens = [t for part in re.split(r"\s*-(?:G-|PD-)?>\s*", words) for t in part.split()]
        assert paper.listed_patterns(tokens) == paper.listed_patterns(seq), key
    assert "..." not in paper.listed_patterns(paper.PAPER_SEQUENCES["xi005"])
    assert paper.PAPER_COEXIST == ("1-1-1", "2-2-1", "4-4-2")
    assert paper.within(0.02 + 1e-16, paper.LANDMARK_TOL)
    assert not paper.within(0.0201, paper.LANDMARK_TOL) and not paper.within(np.nan, 1.0)
