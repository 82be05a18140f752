"""``ikbranch``: the console command's subcommands forward to the ``python -m`` mains."""

from __future__ import annotations

import json
import subprocess
import sys
import tomllib
import types
from pathlib import Path

import pytest

from ikbranch_gym.train import cli

ROOT = Path(__file__).resolve().parents[2]
#: subcommand -> the module ``python -m`` runs, and a line of its own --help.
FORWARDED = {
    "plan": ("ikbranch_gym.train.plan", "usage: ikbranch plan"),
    "train": ("ikbranch_gym.train.__main__", "usage: python -m train "),
    "evaluate": ("ikbranch_gym.train.evaluate", "usage: python -m train.evaluate"),
    "demo": ("ikbranch_gym.train.demo", "usage: python -m train.demo"),
    "sweep": ("ikbranch_gym.train.sweep", "usage: python -m train.sweep"),
    "aggregate": ("ikbranch_gym.train.aggregate", "usage: python -m train.aggregate"),
    "export": ("ikbranch_gym.train.export", "usage: ikbranch export"),
    "warm-up": ("ikbranch_gym.envs.precompile", "usage: ikbranch warm-up"),
}


def test_pyproject_declares_the_console_command():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert project["scripts"] == {"ikbranch": "ikbranch_gym.train.cli:main"}
    assert "ikbranch_gym.train" in tomllib.loads((ROOT / "pyproject.toml").read_text())[
        "tool"]["setuptools"]["packages"]


def test_help_lists_every_subcommand():
    result = subprocess.run([sys.executable, "-m", "train.cli", "--help"],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    listed = [line.split()[0] for line in result.stdout.splitlines()
              if line.startswith("  ") and not line.strip().startswith("-")]
    assert listed == list(FORWARDED) == list(cli.COMMANDS)
    # Listing the commands imports none of them (no torch, no Ray).
    probe = subprocess.run(
        [sys.executable, "-c", "import sys; from ikbranch_gym.train import cli; "
         "cli.main(['--help']); print(sorted(m for m in ('torch', 'ray', 'mujoco', "
         "'ikbranch_gym.train.plan') if m in sys.modules))"],
        capture_output=True, text=True, timeout=120)
    assert probe.stdout.strip().splitlines()[-1] == "[]"


def test_no_command_and_unknown_commands_are_errors(capsys):
    assert cli.main([]) == 2
    assert "usage: ikbranch COMMAND" in capsys.readouterr().err
    assert cli.main(["pla", "--arm", "x"]) == 2
    err = capsys.readouterr().err
    assert "unknown command 'pla'" in err and "did you mean 'plan'?" in err
    assert cli.main(["fly"]) == 2
    err = capsys.readouterr().err
    assert "unknown command 'fly'" in err and "plan, train, evaluate, demo, sweep" in err
    assert "did you mean" not in err
    assert cli.main(["--version"]) == 0
    assert capsys.readouterr().out.startswith("ikbranch ")


@pytest.mark.parametrize(("result", "status"), [(0, 0), (None, 0), (3, 3), ({"env": "x"}, 0)])
def test_arguments_and_status_are_forwarded(monkeypatch, result, status):
    seen = {}

    def fake_import(name):
        def main(argv):
            seen[name] = argv
            return result
        return types.SimpleNamespace(main=main)

    monkeypatch.setattr(cli.importlib, "import_module", fake_import)
    for command, (module, _) in FORWARDED.items():
        argv = ["--flag", "value with space", "-x", "--help-me"]
        assert cli.main([command, *argv]) == status
        assert seen[module] == argv


@pytest.mark.parametrize("command", list(FORWARDED))
def test_subcommand_help_is_the_modules_own(command, capsys):
    with pytest.raises(SystemExit) as exit_info:
        cli.main([command, "--help"])
    assert exit_info.value.code == 0
    assert FORWARDED[command][1] in capsys.readouterr().out


def test_python_m_forms_still_run():
    for module in ("train.plan", "train.evaluate"):
        result = subprocess.run([sys.executable, "-m", module, "--help"], capture_output=True,
                                text=True, timeout=120)
        assert result.returncode == 0 and "usage:" in result.stdout


def test_the_demo_runs_end_to_end_on_a_tiny_budget(tmp_path, capsys):
    # make demo's pipeline: the worked example, training, the evaluation table, the plots
    # and the GIF (rendered for real), on a budget of one rollout.
    from ikbranch_gym.train import demo

    run = tmp_path / "demo"
    assert demo.main(["--run-dir", str(run), "--timesteps", "256", "--episodes", "2"]) == 0
    printed = capsys.readouterr().out
    assert "275.15" in printed and "maskable_ppo" in printed and "dp_oracle" in printed
    results = json.loads((run / "evaluation.json").read_text())
    assert results["env"] == demo.ENV_ID and results["episodes"] == 2
    assert set(results["policies"]) == {"maskable_ppo", *demo.DEMO_BASELINES}
    for name in ("comparison.png", "episode.gif", "model.zip"):
        assert (run / name).stat().st_size > 0, name
    # No held-out evaluation ran within one rollout: no learning curve, and none claimed.
    assert not (run / "learning_curve.png").exists()
    assert "Wrote evaluation.json, comparison.png, episode.gif to" in printed
    import imageio.v3 as iio

    frames = iio.imread(run / "episode.gif", index=None)
    assert frames.ndim == 4 and len(frames) >= demo.FRAMES_PER_MOVE and frames.std() > 10
    # With a checkpoint that won a validation round, the demo evaluates and films that one
    # (the final model.zip, made unreadable here, is not touched).
    (run / "best").mkdir(exist_ok=True)
    (run / "best" / "best_model.zip").write_bytes((run / "model.zip").read_bytes())
    (run / "best" / "best.json").write_text('{"best_mean_reward": -20.0, "timesteps": 128}')
    (run / "model.zip").write_bytes(b"not a model")
    assert demo.main(["--run-dir", str(run), "--timesteps", "256", "--episodes", "2"]) == 0
    assert "best validation return: 128 steps" in capsys.readouterr().out
