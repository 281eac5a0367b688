"""One ``GDM`` shared between Python threads: no call is lost, none is mixed with another, nothing
raises but the caller's own errors.

Calls that change the model run one at a time, each whole; calls that read it run beside each
other and only ever see the model between two changes. A bug (Rust panic) inside a call raises an
``LgdmError`` subclass and the model refuses further calls.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import numpy as np
import pytest

import lgdm
from lgdm._errors import InternalError

THREADS = 4
CALLS_PER_THREAD = 8
#: Insertion as soon as a node has fired once: every call's cluster gets nodes of its own,
#: whatever order the calls arrive in (checked over 400 orders).
EAGER = {"episodic__habituation_threshold": 1.0, "semantic__habituation_threshold": 1.0}


def make_calls(n: int = THREADS * CALLS_PER_THREAD, dim: int = 8, frames: int = 12):
    """``n`` partial_fit calls, each one object: a tight cluster of its own far from the others,
    seen as one sequence, with instance label = the call's index."""
    rng = np.random.default_rng(0)
    calls = []
    for c in range(n):
        centre = rng.normal(0.0, 3.0, dim)
        drift = rng.normal(0.0, 0.02, dim)
        frames_x = [centre + t * drift + rng.normal(0.0, 0.03, dim) for t in range(frames)]
        x = np.asarray(frames_x, dtype=np.float32)
        calls.append({"X": x, "instance": c, "category": c % 4, "sequence": c})
    return calls


def recognised(model: lgdm.GDM, calls) -> list[int]:
    """The calls whose object the model recognises (majority instance over its frames): a call
    that was lost leaves no node of its own and is not recognised."""
    out = []
    for c in calls:
        instance = model.predict(c["X"]).instance
        if np.bincount(instance.clip(0)).argmax() == c["instance"]:
            out.append(c["instance"])
    return out


def run_threads(targets: list[Callable[[], None]]) -> list[BaseException]:
    """Starts every target at once (barrier) and returns the exceptions they raised."""
    errors: list[BaseException] = []
    barrier = threading.Barrier(len(targets))

    def wrap(target: Callable[[], None]) -> None:
        try:
            barrier.wait()
            target()
        except BaseException as e:  # the test reports every exception
            errors.append(e)

    threads = [threading.Thread(target=wrap, args=(t,)) for t in targets]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=120)
        assert not t.is_alive(), "a thread hung"
    return errors


def test_four_threads_partial_fit_one_model_and_no_call_is_lost():
    calls = make_calls()
    model = lgdm.GDM("paper_incremental", seed=0, **EAGER)  # unfitted: the first calls race

    def worker(k: int) -> Callable[[], None]:
        def run() -> None:
            for c in calls[k::THREADS]:
                model.partial_fit(
                    c["X"], instance=c["instance"], category=c["category"], sequence=c["sequence"]
                )

        return run

    errors = run_threads([worker(k) for k in range(THREADS)])
    assert errors == []
    assert recognised(model, calls) == list(range(len(calls)))
    # The check sees a lost call: the same calls in order, one left out.
    missing = lgdm.GDM("paper_incremental", seed=0, **EAGER)
    for c in calls[:5] + calls[6:]:
        missing.partial_fit(
            c["X"], instance=c["instance"], category=c["category"], sequence=c["sequence"]
        )
    assert 5 not in recognised(missing, calls)


def test_calls_in_a_forced_order_give_the_sequential_model():
    """Four threads take turns (call k on thread k % 4, each a new automatic sequence): the model
    is byte for byte the one a single thread makes with the same calls in the same order."""
    calls = make_calls()
    model = lgdm.GDM("paper_incremental", seed=0, **EAGER)
    turn = [0]
    cond = threading.Condition()

    def worker(k: int) -> Callable[[], None]:
        def run() -> None:
            for i in range(k, len(calls), THREADS):
                with cond:
                    cond.wait_for(lambda i=i: turn[0] == i, timeout=60)
                    assert turn[0] == i
                c = calls[i]
                model.partial_fit(c["X"], instance=c["instance"], category=c["category"])
                with cond:
                    turn[0] += 1
                    cond.notify_all()

        return run

    errors = run_threads([worker(k) for k in range(THREADS)])
    assert errors == []
    alone = lgdm.GDM("paper_incremental", seed=0, **EAGER)
    for c in calls:
        alone.partial_fit(c["X"], instance=c["instance"], category=c["category"])
    assert model.to_bytes() == alone.to_bytes()


def test_a_trainer_beside_three_readers():
    """One thread trains (29 calls, then an episode end and a replay) while three read: no
    exception anywhere, every training call applied (the final model equals the sequential
    one), and every snapshot a reader takes is a state between two training calls."""
    calls = make_calls(29)
    first = make_calls(4)[0]

    def fresh() -> lgdm.GDM:
        return lgdm.GDM("paper_incremental", seed=0, **EAGER).fit(
            first["X"], instance=first["instance"], category=first["category"]
        )

    def steps(model: lgdm.GDM):
        for c in calls:
            yield lambda c=c: model.partial_fit(
                c["X"], instance=c["instance"], category=c["category"], sequence=c["sequence"]
            )
        yield model.end_episode
        yield model.replay

    reference = fresh()
    states = {reference.to_bytes()}
    for step in steps(reference):
        step()
        states.add(reference.to_bytes())

    model = fresh()
    done = threading.Event()
    snapshots: set[bytes] = set()
    reads = [0, 0, 0]

    def trainer() -> None:
        try:
            for step in steps(model):
                step()
        finally:
            done.set()

    def predictor(k: int) -> Callable[[], None]:
        def run() -> None:
            x = np.concatenate([c["X"] for c in calls[:8]])
            while not done.is_set() or reads[k] == 0:
                p = model.predict(x)
                assert p.instance.shape == (len(x),)
                assert model.n_nodes_episodic_ >= 2
                reads[k] += 1

        return run

    def snapshotter() -> None:
        while not done.is_set() or reads[2] == 0:
            snapshots.add(model.to_bytes())
            reads[2] += 1

    errors = run_threads([trainer, predictor(0), predictor(1), snapshotter])
    assert errors == []
    assert all(r > 0 for r in reads)
    assert model.to_bytes() == reference.to_bytes()
    assert snapshots <= states, "a reader saw a model in the middle of a call"


def test_a_panic_inside_a_call_is_an_lgdm_error_and_the_model_refuses_further_calls():
    calls = make_calls(3)
    model = lgdm.GDM("paper_incremental", seed=0)
    for c in calls:
        model.partial_fit(c["X"], instance=c["instance"], category=c["category"])
    other = lgdm.GDM.from_bytes(model.to_bytes())
    with pytest.raises(InternalError, match="internal error") as info:
        model._engine()._panic_for_tests()
    assert isinstance(info.value, lgdm.LgdmError)
    assert isinstance(info.value, RuntimeError)
    for call in (
        lambda: model.predict(calls[0]["X"]),
        lambda: model.partial_fit(calls[0]["X"]),
        lambda: model.to_bytes(),
        lambda: model.n_nodes_episodic_,
        lambda: model.replay(),
    ):
        with pytest.raises(InternalError, match="load it again from a checkpoint"):
            call()
    # Other models, even copies of it, are unaffected.
    assert other.predict(calls[0]["X"]).instance.shape == (12,)
