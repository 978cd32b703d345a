"""The wheel: what a non-editable install holds, and that it runs from an empty folder.

A wheel is built from the checkout (``pip wheel --no-build-isolation``: the setuptools of this
environment, a dev dependency) and installed with ``--no-deps`` into a fresh venv whose
dependencies come from this environment's site-packages through a ``.pth`` line (the editable
install's finder there is not run: a ``.pth`` line adds a folder, it does not process the
``.pth`` files inside it). So ``tuner`` and ``gaits`` are imported from the wheel alone, and the
shipped studies and sets must be in it.
"""

import os
import shutil
import subprocess
import sys
import sysconfig
import time
import tomllib
import venv

import pytest

from conftest import ROOT, run_in_process


def test_the_package_list_names_every_package_of_the_tree():
    conf = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(conf["packages"])
    tree = {".".join(p.parent.relative_to(ROOT).parts) for top in ("gaits", "tuner")
            for p in (ROOT / top).rglob("__init__.py")}
    assert tree <= listed, f"packages missing from pyproject.toml: {sorted(tree - listed)}"
    mapped = {k: ROOT / v for k, v in conf["package-dir"].items()}
    assert all(p.is_dir() for p in mapped.values())
    assert listed - tree == {"tuner.shipped", "tuner.shipped.results", "tuner.shipped.starts"}


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"                 # a copy: the build writes build/ and *.egg-info beside its sources
    for name in ("pyproject.toml", "README.md"):
        src.mkdir(exist_ok=True)
        shutil.copy(ROOT / name, src / name)
    for name in ("gaits", "tuner", "studies"):
        shutil.copytree(ROOT / name, src / name, ignore=shutil.ignore_patterns("__pycache__", "*.so"))
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
                        "-w", str(tmp / "dist"), str(src)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    wheel = next((tmp / "dist").glob("gait_tuner-*.whl"))
    env_dir = tmp / "venv"
    venv.EnvBuilder(with_pip=False).create(env_dir)
    py = env_dir / "bin" / "python"
    site = subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                          capture_output=True, text=True, check=True).stdout.strip()
    with open(os.path.join(site, "dev-deps.pth"), "w") as f:
        f.write(sysconfig.get_paths()["purelib"] + "\n")
    r = subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "--no-deps", "-q", str(wheel)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    work = tmp / "empty"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH",)}
    env["MPLBACKEND"] = "Agg"
    return env_dir / "bin" / "gait-tuner", py, work, env


def _run(installed, *args, timeout=600):
    exe, _, work, env = installed
    return subprocess.run([str(exe), *args], capture_output=True, text=True, cwd=work, env=env, timeout=timeout)


def test_the_wheel_imports_from_itself_not_the_checkout(installed):
    _, py, work, env = installed
    r = subprocess.run([str(py), "-c", "import tuner, gaits, tuner.params_io as p; "
                        "print(tuner.__file__); print(gaits.__file__); print(p.SHIPPED_DIR)"],
                       capture_output=True, text=True, cwd=work, env=env)
    assert r.returncode == 0, r.stderr
    for line in r.stdout.split():
        assert str(ROOT) not in line, line
    assert r.stdout.split()[2].endswith(os.path.join("tuner", "shipped"))


def test_the_installed_wheel_lists_the_shipped_studies_and_sets(installed):
    studies = _run(installed, "studies")
    assert studies.returncode == 0, studies.stderr
    for name in (p.stem for p in (ROOT / "studies").glob("*.yaml")):
        assert name in studies.stdout, name
    sets = _run(installed, "sets")
    assert sets.returncode == 0, sets.stderr
    for name in (p.stem for p in (ROOT / "studies" / "results").glob("*.yaml")):
        assert name in sets.stdout, name


def test_the_installed_wheel_tunes_a_shipped_study_from_an_empty_folder(installed):
    r = _run(installed, "tune", "quickstart", "--trials", "2")
    assert r.returncode == 0, r.stderr[-2000:]
    assert "best trial" in r.stdout
    r = _run(installed, "export", "quickstart", "--out", "best.yaml")
    assert r.returncode == 0, r.stderr[-2000:]
    assert (installed[2] / "best.yaml").exists()
    # a study whose base is a file beside it (starts/)
    _, py, work, env = installed
    r = subprocess.run([str(py), "-c", "from tuner.search.study import load_study; "
                        "print(load_study('kidsize-engine-carpet4').kind)"], capture_output=True, text=True,
                       cwd=work, env=env)
    assert r.returncode == 0 and r.stdout.strip() == "match", r.stderr[-2000:]
    r = _run(installed, "simulate", "--params", "kidsize-engine-carpet4", "--surface", "carpet4",
             "--command", "0.1,0,0", "--duration", "2")
    assert r.returncode == 0, r.stderr[-2000:]


def test_the_robot_part_lists_every_package_of_gaits():
    conf = tomllib.loads((ROOT / "robot" / "pyproject.toml").read_text())
    listed = set(conf["tool"]["setuptools"]["packages"])
    tree = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "gaits").rglob("__init__.py")}
    assert listed == tree
    assert conf["project"]["dependencies"] == ["numpy>=1.26", "pyyaml>=6.0"]


def test_the_robot_part_installs_and_runs_its_loop_without_the_simulator(tmp_path):
    """Built from the checkout, installed into a fresh venv with pip (its numpy and PyYAML from the
    package index or pip's cache), it runs the loop on a robot file; MuJoCo, Optuna, CasADi and the
    tuner are not there."""
    src = tmp_path / "src"
    shutil.copytree(ROOT / "robot", src / "robot")
    shutil.copytree(ROOT / "gaits", src / "gaits", ignore=shutil.ignore_patterns("__pycache__"))
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
                        "-w", str(tmp_path / "dist"), str(src / "robot")], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    wheel = next((tmp_path / "dist").glob("gait_tuner_robot-*.whl"))
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=False).create(env_dir)       # this pip installs into it (ensurepip took ~4 s)
    r = subprocess.run([sys.executable, "-m", "pip", "--python", str(env_dir / "bin" / "python"), "install", "-q",
                        f"{wheel}[dynamixel]"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    py = env_dir / "bin" / "python"
    probe = subprocess.run([str(py), "-c", "import importlib.util as u; print([m for m in ('mujoco', 'optuna', "
                            "'casadi', 'tuner', 'scipy') if u.find_spec(m)])"], capture_output=True, text=True,
                           cwd=tmp_path)
    assert probe.stdout.strip() == "[]", probe.stdout + probe.stderr
    robot = tmp_path / "robot.yaml"
    r = run_in_process(['robot', 'export', 'kidsize', '--out', str(robot)])
    assert r.returncode == 0, r.stderr
    r = subprocess.run([str(env_dir / "bin" / "gait-tuner-loop"), str(ROOT / "studies" / "results" /
                        "kidsize-engine-carpet4.yaml"), "--dry-run", "--seconds", "1", "--robot", str(robot)],
                       capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "100 ticks" in r.stdout and "robot kidsize" in r.stdout
    # the same loop, from that venv, walks the simulated robot through the bus another process serves
    link = tmp_path / "bus"
    server = subprocess.Popen([sys.executable, "-m", "tuner.cli", "bus", "serve", "--robot", "kidsize", "--surface",
                               "carpet4", "--link", str(link)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while not link.exists() and server.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert link.exists(), server.communicate(timeout=5)
        r = subprocess.run([str(env_dir / "bin" / "gait-tuner-loop"), str(ROOT / "studies" / "results" /
                            "kidsize-engine-carpet4.yaml"), "--robot", str(robot), "--port", str(link), "--seconds",
                            "1", "--watchdog", "300"], capture_output=True, text=True, cwd=tmp_path, timeout=300)
        out, _ = server.communicate(timeout=120)
    finally:
        if server.poll() is None:
            server.kill()
    assert r.returncode == 0 and "walked its time" in r.stdout, r.stdout + r.stderr[-2000:]
    assert "served" in out and "the client turned the torque off" in out, out
