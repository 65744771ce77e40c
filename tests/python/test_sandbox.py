"""The Python module `tumble` (ctest `python.sandbox`): the hash of 60 frames of rope equal to the
`tumble` program's own, the state as NumPy arrays of the right shapes, events, dumps, profiles, replays,
and every public call given bad arguments raising, never crashing the interpreter."""

import json
import os
import signal
import subprocess
import sys
import warnings

import numpy as np
import pytest

import tumble

TUMBLE = os.environ["TUMBLE_BINARY"]


def program_hash(tmp_path, scenario, frames, *sets):
    """The `tumble` program's dump hash of the last frame (16 hex digits after 0x)."""
    dump = tmp_path / "state.jsonl"
    args = [TUMBLE, "run", scenario, "--no-render", "--quiet", "--frames", str(frames), "--dump", str(dump),
            "--out", str(tmp_path / "out")]
    for s in sets:
        args += ["--set", s]
    subprocess.run(args, check=True)
    return int(json.loads(dump.read_text().splitlines()[-1])["hash"], 16)


def test_rope_hash_after_60_frames_equals_the_programs(tmp_path):
    sim = tumble.Sandbox("rope")
    sim.step(60)
    assert sim.frame == 60
    assert sim.hash() == program_hash(tmp_path, "rope", 60)


def test_threads_and_sets_give_the_programs_bits(tmp_path):
    sim = tumble.Sandbox("rope", set=["chain.rope.stiffness=900"], threads=2)
    sim.step(30)
    assert sim.hash() == program_hash(tmp_path, "rope", 30, "chain.rope.stiffness=900")


def test_state_as_numpy_arrays():
    sim = tumble.Sandbox("rope", threads=1)
    assert sim.entities["chain"] == "springs"
    x0 = sim.x("chain")
    assert x0.shape == (31, 3) and x0.dtype == np.float64
    # the rope starts along +x from its pin at (0, 2.2, 0): 2 m in 30 segments
    assert np.allclose(x0[0], [0.0, 2.2, 0.0])
    assert np.isclose(np.linalg.norm(np.diff(x0, axis=0), axis=1).sum(), 2.0, rtol=1e-9)
    sim.step(10)
    assert sim.v("chain").shape == (31, 3)
    assert np.isclose(sim.time, 10 * 16 * sim.dt)
    # the pinned end does not move; the free end falls
    assert np.allclose(sim.x("chain")[0], x0[0])
    assert sim.x("chain")[-1][1] < x0[-1][1]


@pytest.mark.parametrize("demo", ["fountain", "fireworks", "rope", "curtain", "fem_jelly", "jelly", "pile",
                                  "pyramid2d", "harbour"])
def test_x_and_v_are_the_dumps_rows(demo):
    # x() and v() read springs and particles straight from their components and everything else through
    # the entity's dump: either way the very numbers of the whole dump line, for every entity that has them
    sim = tumble.Sandbox(demo, threads=1)
    sim.step(12)
    dump = sim.dump()["entities"]
    checked = 0
    for name in sim.entities:
        for field, read in (("x", sim.x), ("v", sim.v)):
            if field not in dump[name]:
                continue
            rows = np.array(dump[name][field], dtype=np.float64).reshape(-1, sim.x(name).shape[1])
            assert np.array_equal(read(name), rows, equal_nan=True), (demo, name, field)
            checked += 1
    assert checked > 0


def test_a_2d_body_has_two_columns():
    sim = tumble.Sandbox("pyramid2d", threads=1)
    name, kind = next((n, k) for n, k in sim.entities.items() if k == "rigid2d")
    assert sim.x(name).shape[1] == 2
    assert sim.v(name).shape[1] == 2


def test_apply_an_impulse_changes_the_velocity():
    a = tumble.Sandbox("rope", threads=1)
    b = tumble.Sandbox("rope", threads=1)
    b.apply("chain", "impulse", value=[0.0, 0.0, 3.0])
    a.step(1)
    b.step(1)
    assert b.v("chain")[:, 2].sum() > a.v("chain")[:, 2].sum() + 1.0
    assert a.hash() != b.hash()


def test_set_event_and_dump_and_profile():
    sim = tumble.Sandbox("rope", threads=1)
    sim.set("scene.gravity=[0.0, 0.0, 0.0]")
    sim.step(2)
    dump = sim.dump()
    assert dump["frame"] == 2 and "chain" in dump["entities"]
    assert int(dump["hash"], 16) == sim.hash()
    profile = sim.profile()
    assert profile["scene"] == "rope" and profile["frames"] == 2


def test_record_then_verify(tmp_path, capfd):
    path = str(tmp_path / "r.tumble")
    sim = tumble.Sandbox("rope", threads=1)
    sim.record(path)
    sim.apply("chain", "impulse", value=[0.0, 1.0, 0.0])
    sim.step(20)
    sim.finish_recording()
    capfd.readouterr()
    assert tumble.verify(path, threads=2) is True
    assert capfd.readouterr().err == "", "the verdict is the return value, not a line on stderr"
    assert subprocess.run([TUMBLE, "replay", path, "--verify", "--no-render", "--quiet",
                           "--out", str(tmp_path / "o")]).returncode == 0


def test_bad_input_raises_scenario_error_naming_it():
    with pytest.raises(tumble.ScenarioError, match="stifness.*did you mean 'stiffness'"):
        tumble.Sandbox("rope", set=["chain.rope.stifness=5"])
    assert issubclass(tumble.ScenarioError, ValueError)
    with pytest.raises(tumble.ScenarioError, match="no_such_demo"):
        tumble.Sandbox("no_such_demo")


@pytest.mark.parametrize("call", [
    lambda: tumble.Sandbox(None),
    lambda: tumble.Sandbox("rope", set="chain.rope.stiffness=5x"),
    lambda: tumble.Sandbox("rope", threads=0),
    lambda: tumble.Sandbox("rope", threads="two"),
    lambda: tumble.Sandbox("/dev/null"),
])
def test_bad_constructor_arguments_raise(call):
    with pytest.raises((ValueError, TypeError)):
        call()


@pytest.fixture(scope="module")
def rope():
    return tumble.Sandbox("rope", threads=1)


@pytest.mark.parametrize("call", [
    lambda s: s.step(-1),
    lambda s: s.step("x"),
    lambda s: s.step(2**40),
    lambda s: s.x("ghost"),
    lambda s: s.v(3),
    lambda s: s.apply("ghost", "impulse", value=[0, 0, 1]),
    lambda s: s.apply("chain", "no_such_action"),
    lambda s: s.apply("chain", "impulse", value=[0, 1]),
    lambda s: s.apply("chain", "impulse", value="up"),
    lambda s: s.apply("chain", "impulse", value=[0, 0, 1], position=[1, 2]),
    lambda s: s.set("chain.rope.segments=3"),
    lambda s: s.set("not a key"),
    lambda s: s.record("/no/such/folder/r.tumble"),
    lambda s: tumble.verify("/no/such/file.tumble"),
    lambda s: tumble.verify(__file__),
])
def test_bad_arguments_raise_and_leave_the_sandbox_working(rope, call):
    with pytest.raises((ValueError, TypeError, RuntimeError)):
        call(rope)
    before = rope.frame
    rope.step(1)
    assert rope.frame == before + 1


def test_record_after_stepping_is_refused():
    sim = tumble.Sandbox("rope", threads=1)
    sim.step(1)
    with pytest.raises(tumble.ScenarioError, match="before the first step"):
        sim.record("/tmp/never.tumble")


def test_two_threads_sharing_one_sandbox_take_turns():
    # step() runs without the GIL: before each Sandbox had a lock, a read during a step corrupted the heap
    # (malloc abort) and two threads stepping at once crashed
    import threading
    sim = tumble.Sandbox("fountain", threads=1)
    errors = []

    def steps():
        try:
            for _ in range(40):
                sim.step(2)
        except Exception as e:  # pragma: no cover - reported below
            errors.append(e)

    workers = [threading.Thread(target=steps) for _ in range(2)]
    for w in workers:
        w.start()
    while any(w.is_alive() for w in workers):
        assert sim.x("jet").shape[1] == 3
    for w in workers:
        w.join()
    assert not errors and sim.frame == 160


def test_verify_puts_back_the_callers_signal_handlers(tmp_path):
    # it left SIGINT and SIGTERM at SIG_DFL in the OS (Python's own table of handlers, which
    # signal.getsignal reads, never saw it): after one verify, Ctrl-C killed Python. In a child process,
    # so that a handler lost kills that, not the tests: after verify, SIGTERM and SIGINT reach Python.
    script = tmp_path / "child.py"
    script.write_text(
        "import os, signal, tumble\n"
        f"path = {str(tmp_path / 'r.tumble')!r}\n"
        "sim = tumble.Sandbox('rope', threads=1)\n"
        "sim.record(path)\n"
        "sim.step(3)\n"
        "sim.finish_recording()\n"
        "got = []\n"
        "signal.signal(signal.SIGTERM, lambda s, f: got.append(s))\n"
        "assert tumble.verify(path, threads=1) is True\n"
        "os.kill(os.getpid(), signal.SIGTERM)\n"
        "try:\n"
        "    os.kill(os.getpid(), signal.SIGINT)\n"
        "except KeyboardInterrupt:\n"
        "    got.append('interrupt')\n"
        "print(got)\n")
    child = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120,
                           env=dict(os.environ))
    assert child.returncode == 0, child.stderr
    assert child.stdout.strip() == "[" + str(int(signal.SIGTERM)) + ", 'interrupt']"


@pytest.mark.parametrize("kwargs", [
    dict(value=[float("nan"), 0.0, 0.0]),
    dict(value=[float("inf"), 0.0, 0.0]),
    dict(value=[1e12, 0.0, 0.0]),
    dict(value=[0.0] * 4097),
    dict(value=[0.0, 0.0, 1.0], position=[0.0, float("nan"), 0.0]),
])
def test_apply_refuses_what_a_replay_cannot_hold(rope, kwargs):
    # accepted before, the NaN made the rope NaN, and a replay holding 1e12 could not be read back
    with pytest.raises(tumble.ScenarioError, match="finite number within|too many numbers"):
        rope.apply("chain", "impulse", **kwargs)


def test_disturb_refuses_a_non_finite_radius_or_amount():
    pond = tumble.Sandbox("pond", threads=1)
    for kwargs in (dict(radius=float("inf"), amount=0.1), dict(radius=0.5, amount=float("nan"))):
        with pytest.raises(tumble.ScenarioError, match="finite number within"):
            pond.apply("pond", "disturb", position=[0.0, 0.0, 0.0], **kwargs)


def test_a_run_that_blew_up_as_recorded_verifies(tmp_path, capfd):
    # a failure the recording met too is not a divergence (verify raised "stopped before its end" and
    # printed the blow-up on stderr)
    path = str(tmp_path / "r.tumble")
    sim = tumble.Sandbox("rope", set=["chain.rope.integrator=symplectic_euler", "chain.rope.stiffness=1e9"],
                         threads=1)
    sim.record(path)
    with pytest.warns(RuntimeWarning, match="blew up"):
        sim.step(5)
    sim.finish_recording()
    assert sim.failures(), "the stiff rope should blow up under symplectic Euler"
    capfd.readouterr()
    assert tumble.verify(path, threads=1) is True
    assert capfd.readouterr().err == ""


def test_a_second_recording_is_refused_and_the_first_kept(tmp_path):
    sim = tumble.Sandbox("rope", threads=1)
    sim.record(str(tmp_path / "a.tumble"))
    with pytest.raises(tumble.ScenarioError, match="already being recorded"):
        sim.record(str(tmp_path / "b.tumble"))
    sim.step(4)
    sim.finish_recording()
    assert tumble.verify(str(tmp_path / "a.tumble"), threads=1) is True


@pytest.mark.parametrize("threads", [0, -5, 100000])
def test_verify_refuses_a_thread_count_out_of_range(tmp_path, threads):
    with pytest.raises(ValueError, match="threads"):
        tumble.verify(str(tmp_path / "none.tumble"), threads=threads)


def test_scenario_errors_carry_file_line_and_column(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[scene]\nname = "bad"\ndt = -1.0\n')
    with pytest.raises(tumble.ScenarioError) as caught:
        tumble.Sandbox(bad)  # a pathlib.Path is taken too
    e = caught.value
    assert e.file == str(bad) and e.line == 3 and e.column > 0 and "dt" in e.message
    assert str(e).startswith(f"{bad}:3:")
    assert tumble.ScenarioError.__doc__ and tumble.ReplayError.__doc__


def test_a_sandbox_never_initialised_raises_rather_than_crashes():
    with pytest.raises((TypeError, RuntimeError)):
        tumble.Sandbox.__new__(tumble.Sandbox).frame


def test_an_entity_without_state_is_named_as_such():
    with pytest.raises(tumble.ScenarioError, match="'wind' has no state the dump lists"):
        tumble.Sandbox("curtain", threads=1).x("wind")


def test_a_misspelt_entity_is_given_the_nearest_name():
    # x(), v() and dump-like reads said "no entity 'chian' in the scene" alone; apply() already suggested
    sim = tumble.Sandbox("rope", threads=1)
    for read in (sim.x, sim.v):
        with pytest.raises(tumble.ScenarioError, match=r"no entity 'chian' in the scene \(did you mean 'chain'\?\)"):
            read("chian")
    # and only names with a state are suggested: the curtain's wind has none (it suggested 'wind')
    with pytest.raises(tumble.ScenarioError) as raised:
        tumble.Sandbox("curtain", threads=1).x("wnd")
    assert "did you mean" not in str(raised.value)


def test_a_blow_up_while_stepping_is_warned_of_once():
    # step() returned as if all were well: the blow-up was in failures() alone
    sim = tumble.Sandbox("rope", set=["chain.rope.integrator=symplectic_euler", "chain.rope.stiffness=1e9"],
                         threads=1)
    with pytest.warns(RuntimeWarning, match="blew up|not finite") as caught:
        sim.step(5)
    assert [str(w.message) for w in caught] == sim.failures()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a failure already warned of is not warned of again
        sim.step(2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        calm = tumble.Sandbox("rope", threads=1)
        calm.step(30)
        assert calm.failures() == []


def test_verify_of_a_replay_cut_short_raises(tmp_path):
    # it returned True for the frames the file held: 0 of them, for a file cut after its header
    path = tmp_path / "r.tumble"
    sim = tumble.Sandbox("rope", threads=1)
    sim.record(str(path))
    sim.step(20)
    sim.finish_recording()
    data = path.read_bytes()
    path.write_bytes(data[: len(data) * 2 // 3])
    # and the message did not name the file
    with pytest.raises(RuntimeError, match=r"r\.tumble: the replay is cut short at byte"):
        tumble.verify(path, threads=1)
