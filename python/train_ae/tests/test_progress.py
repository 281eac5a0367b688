import io

from train_ae.progress import ProgressBar


def test_a_log_gets_a_line_per_tenth_and_one_at_the_end():
    log = io.StringIO()
    with ProgressBar(25, "epoch 1/3", stream=log) as bar:
        for _ in range(25):
            bar.update(1, loss=0.5)
    lines = log.getvalue().splitlines()
    # 25 steps cross a tenth at 3, 5, 8, 10, 13, 15, 18, 20, 23; then the finished bar.
    assert [int(x.split()[3].split("/")[0]) for x in lines] == [3, 5, 8, 10, 13, 15, 18, 20,
                                                                  23, 25]
    assert all(x.startswith("epoch 1/3 [") and "loss 0.5" in x for x in lines)
    assert "\r" not in log.getvalue()


def test_a_disabled_bar_writes_nothing():
    log = io.StringIO()
    with ProgressBar(5, "x", stream=log, enabled=False) as bar:
        bar.update(5)
    assert log.getvalue() == ""
