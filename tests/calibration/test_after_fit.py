"""The chain after a refit (pedmesh.fitting.after_fit) runs its steps in order, marks each
done, resumes after the last done, and stops at the first that fails."""

import sys

from pedmesh.fitting.after_fit import Step, run_chain, steps


def _step(name, code):
    return Step(name, name, (sys.executable, "-c", code))


def test_the_chain_resumes_and_stops_at_a_failure(tmp_path):
    out = tmp_path / "order.txt"
    write = f"open({str(out)!r}, 'a').write('{{}}\\n')"
    chain = [_step("a", write.format("a")), _step("b", "raise SystemExit(3)"),
             _step("c", write.format("c"))]
    logs = tmp_path / "logs"
    assert run_chain(chain, logs) == 3
    assert out.read_text() == "a\n"
    assert (logs / "a.done").is_file() and not (logs / "b.done").exists()
    assert (logs / "b.log").is_file()
    chain[1] = _step("b", write.format("b"))
    assert run_chain(chain, logs) == 0
    assert out.read_text() == "a\nb\nc\n"  # (a not again)


def test_the_steps_name_scripts_that_exist():
    from pedmesh.fitting.after_fit import ROOT

    for s in steps("corner"):
        script = s.argv[1]
        if script.endswith(".py"):
            assert (ROOT / script).is_file(), s
    assert [s.name for s in steps("corner")][:3] == ["preset", "law", "eos"]
