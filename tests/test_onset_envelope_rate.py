"""The restarted envelope test's crossings on noise (`skin.bench.envelope_rate`, skin bench
envelope-rate): one test a sample, the count the detector's ``z`` is the quantile of, holds."""

import json

import pytest

from skin.bench.envelope_rate import envelope_false_alarms
from skin.cli import main


def test_the_restarted_test_crosses_no_more_often_than_one_test_a_sample():
    out = envelope_false_alarms("low-cost", hours=0.25, taxels=32, seed=1)
    assert out["taxel_hours"] == 8.0
    for z in (3.0, 3.5):
        # hundreds of crossings: a count, and below the bound (low-cost: about 0.65 of it)
        assert 0.4 * out["per_sample_bound"][z] < out["rate"][z] < out["per_sample_bound"][z]
    assert out["rate"][3.0] > out["rate"][3.5] > out["rate"][4.0]
    assert 4.6 < out["z_per_sample"] < 4.8
    # with the flat margin too (the detector's, the smaller of the two once settled): the
    # union's count, at least the table's and at most the table's and the flat one's together
    for z in (3.0, 3.5, 4.0):
        assert out["rate"][z] <= out["rate_with_flat"][z] <= (out["rate"][z]
                                                              + out["rate_flat_alone"])
    assert out["flat_sigmas"] == pytest.approx(11.14, abs=0.01)  # 8 x 0.927 / 0.666


def test_with_the_faster_reading_the_union_still_crosses_less_than_one_test_a_sample():
    # fast-film's detector also tests the fall on a reading smoothed over ~3 ms: two tests a
    # sample at one z, whose union is counted; it stays under the one-test bound the z is
    # the quantile of (16 taxel-hours at --hours 0.5: 0.0625 per taxel-hour at z 5.43)
    out = envelope_false_alarms("fast-film", hours=0.02, taxels=16, seed=2)
    assert out["envelope_tau"] == pytest.approx(0.00293, abs=1e-5)
    # the detector's z: the quantile of half the target per sample (two tests share it)
    assert out["z_per_sample"] == pytest.approx(5.555, abs=1e-3)
    for z in (3.0, 3.5):
        assert 0.4 * out["per_sample_bound"][z] < out["rate"][z] < out["per_sample_bound"][z]
    assert envelope_false_alarms("low-cost", hours=0.001, taxels=2)["envelope_tau"] is None


def test_skin_bench_envelope_rate_prints_one_json_document(capsys):
    assert main(["bench", "envelope-rate", "--sensor", "low-cost", "--hours", "0.02",
                 "--taxels", "4", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["sensor"] == "low-cost" and set(out["rate"]) == set(out["per_sample_bound"])
    assert set(out["rate_with_flat"]) == set(out["rate"])
