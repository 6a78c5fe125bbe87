"""The standard-library reference: its layer map and its refusal without the library."""

import importlib.util

import pytest

from dc_lesson.nn.policies import GaussianPolicy
from dc_lesson.perf import imitation_ref


def test_the_layer_map_covers_our_policy_exactly():
    ours = GaussianPolicy(8, 2, imitation_ref.HIDDEN, log_std_init=0.0).state_dict()
    assert set(imitation_ref.LAYERS) == set(ours)
    # the same recipe as table1's bc-lib row, so the comparison is like for like
    from dc_lesson.experiments.studies import table1
    from dc_lesson.algorithms import bc
    cfg = table1.learner_config(table1.ROWS["bc-lib"], None, 0)
    assert cfg == bc.library_recipe(0)
    assert tuple(cfg.hidden) == imitation_ref.HIDDEN and cfg.batch_size == imitation_ref.BATCH


@pytest.mark.skipif(importlib.util.find_spec("imitation") is not None,
                    reason="imitation is installed here")
def test_without_imitation_it_says_how_to_install_it_and_computes_nothing(tmp_path, capsys):
    out = tmp_path / "ref.json"
    with pytest.raises(SystemExit) as e:
        imitation_ref.main(["--out", str(out)])
    assert e.value.code == 2 and not out.exists()
    assert "imitation 1.0.1" in capsys.readouterr().err
