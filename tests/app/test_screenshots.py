"""The README's pictures show what their captions say: the session behind the novel picture
that `make screenshots` takes, run headless, ends judged novel with a GPIS surface.

The picture's object, seed and step count are read from the Makefile's `screenshots`
target, so the test follows any change to it. The object is one the bundled protocol judges
novel in every trial (mug_2 is novel from step 17 on in seeds 0-11), so the assertion does
not hang on where one trajectory ends.
"""

import importlib.util
import shlex
from pathlib import Path

import numpy as np
import pytest

from tactile_viz.engine import PriorLibrary, bundled_names, load_bundled
from tactile_viz.engine.session import Session, make_truth, session_preset

REPO_ROOT = Path(__file__).resolve().parents[2]


def screenshot_commands(makefile=REPO_ROOT / "Makefile"):
    """The app.py options of each window picture of the `screenshots` target, by the
    picture's file name (``{"app_novel_mug2.png": ["--object", "mug_2", ...]}``)."""
    commands, in_target = {}, False
    for line in makefile.read_text().splitlines():
        if not line.startswith("\t"):
            in_target = line.startswith("screenshots:")
            continue
        words = shlex.split(line) if in_target else []
        if "app.py" in words and "--screenshot" in words:
            argv = words[words.index("app.py") + 1:]
            commands[Path(argv[argv.index("--screenshot") + 1]).name] = argv
    return commands


@pytest.fixture(scope="module")
def launcher():
    spec = importlib.util.spec_from_file_location("app_launcher", REPO_ROOT / "app.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def novel_args(launcher):
    novel = [name for name in screenshot_commands() if name.startswith("app_novel")]
    assert len(novel) == 1, f"one novel picture in the Makefile's screenshots target: {novel}"
    return launcher.parse_args(screenshot_commands()[novel[0]])


def test_every_window_picture_is_in_the_docs():
    names = set(screenshot_commands())
    assert {"app_known", "app_novel", "app_learned"} == {name.rsplit("_", 1)[0]
                                                         for name in names}
    docs = (REPO_ROOT / "docs" / "app.md").read_text()
    assert all(f"screenshots/{name}" in docs for name in names)
    assert all((REPO_ROOT / "screenshots" / name).is_file() for name in names)


def test_the_novel_picture_is_the_apps_own_session(launcher, novel_args):
    """The session below is the one the app builds from the same options."""
    assert novel_args.object in bundled_names("novel") and not novel_args.learn_first
    scene = launcher.build_scene(novel_args)
    truth = make_truth(load_bundled(novel_args.object), rng=[novel_args.seed, 0])
    np.testing.assert_allclose(scene.truth.rotation, truth.rotation)
    np.testing.assert_allclose(scene.truth.translation, truth.translation)
    assert scene.active_library().names == bundled_names("known")
    assert (scene.strategy, scene.seed) == ("gpis-dhd", novel_args.seed)
    assert scene.params == session_preset("recommended")
    assert scene.sensor_noise == (0.0, 0.0) and scene.sensor_outliers == 0.0


def test_the_novel_picture_ends_judged_novel_with_a_gpis_surface(novel_args):
    truth = make_truth(load_bundled(novel_args.object), rng=[novel_args.seed, 0])
    session = Session.simulated(truth, PriorLibrary.bundled("known"), "gpis-dhd",
                      session_preset("recommended"), seed=novel_args.seed)
    for _ in range(novel_args.steps):  # as app.py steps before its screenshot
        if session.terminated:
            break
        session.step()
    last = session.latest
    assert last.novel, f"{novel_args.object} ends judged {last.map_class} at step {last.step}"
    assert len(last.gpis_faces) > 0
    variance = np.asarray(last.gpis_variance)
    assert variance.shape == (len(last.gpis_vertices),) and np.all(np.isfinite(variance))
