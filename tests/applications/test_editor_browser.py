"""The map editor page (``sgjax edit``, docs/editor.md) driven in headless Chromium.

A real ``sgjax edit`` runs as a subprocess for the drawing, play and undo tests, and the same
server in a thread of the test process for each map of the open-and-save tests; one browser
serves every test of the module. Drawing goes through real mouse and keyboard events
(Selenium's ActionChains at canvas offsets computed with ``window.sgjaxEditor.worldToScreen``).
Screenshots of each state go to ``tmp_path / "screenshots"``; with
``SGJAX_EDITOR_SCREENSHOTS=docs`` the key ones are also copied to ``docs/img/editor_*.png``
(otherwise nothing is written inside the repository).

Needs Chromium and its driver (Debian packages ``chromium chromium-driver``) and the pip package
``selenium``; skipped without them. Selenium Manager is never used (nothing is downloaded).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

try:
    from selenium import webdriver
    from selenium.common.exceptions import TimeoutException, WebDriverException
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.actions.action_builder import ActionBuilder
    from selenium.webdriver.common.actions.mouse_button import MouseButton
    from selenium.webdriver.common.actions.wheel_input import ScrollOrigin
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys
    from selenium.webdriver.support.ui import Select, WebDriverWait
except ImportError:  # pragma: no cover - depends on the machine
    webdriver = None

# About a minute in all (Chromium, 27 maps opened and saved): the quick tier leaves it to CI,
# which runs it, and the slow mark sends the file to a worker early (tests/conftest.py).
pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[2]
SHIPPED = sorted((REPO / "maps").glob("*.json"))
from shared_data import SG2MAPS, require  # noqa: E402 (SocialGym 2.0's maps, beside it)

SG2_FOLDERS = sorted(p.name for p in SG2MAPS.iterdir() if p.is_dir()) if SG2MAPS.is_dir() else []
DOCS_IMG = REPO / "docs" / "img"
WAIT = 60  # s: the longest a page state may take to appear (a check of a big imported map)
MISSING = ("needs Chromium, its driver and Selenium: apt-get install chromium chromium-driver; "
           "pip install selenium")


# ------------------------------------------------------------------ the server


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Server:
    """An ``sgjax edit ... --no-browser`` subprocess on a free port (started at once; ``url``
    waits until it answers)."""

    def __init__(self, args: list[str], cwd: Path):
        self.port = _free_port()
        self.log = cwd / f"server-{self.port}.log"
        self._log = self.log.open("w")
        self.process = subprocess.Popen(
            [sys.executable, "-m", "sgjax.command", "edit", *args, "--port", str(self.port),
             "--no-browser"], cwd=cwd, stdout=self._log, stderr=subprocess.STDOUT)
        self._ready = False

    @property
    def url(self) -> str:
        """The page's address as ``sgjax edit`` printed it (``http://127.0.0.1:PORT/?token=...``),
        once the server answers an API call with that token."""
        base = f"http://127.0.0.1:{self.port}/"
        deadline = time.monotonic() + WAIT
        while not self._ready:
            if self.process.poll() is not None:
                raise AssertionError(f"sgjax edit exited ({self.process.returncode}):\n"
                                     f"{self.log.read_text()}")
            if time.monotonic() > deadline:
                raise AssertionError(f"sgjax edit did not answer in {WAIT} s:\n"
                                     f"{self.log.read_text()}")
            printed = re.search(r" at (http://\S+\?token=(\S+)) ", self.log.read_text())
            if printed is None:
                time.sleep(0.1)
                continue
            self.printed, self.token = printed.group(1), printed.group(2)
            request = urllib.request.Request(base + "api/session",
                                             headers={"X-Sgjax-Token": self.token})
            try:
                with urllib.request.urlopen(request, timeout=5) as answer:
                    self._ready = answer.status == 200
            except (urllib.error.URLError, ConnectionError, TimeoutError):
                time.sleep(0.1)
        assert self.printed.startswith(base), self.printed
        return self.printed

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self._log.close()


@contextlib.contextmanager
def server(args: list[str], cwd: Path):
    s = Server(args, cwd)
    try:
        yield s
    finally:
        s.stop()


class InProcessServer:
    """The editor's server for one map in a thread of the test process (no second import of
    sgjax and jax: the open-and-save tests open 27 maps). ``sgjax edit`` itself, as a
    subprocess, serves the drawing, play and undo tests (:class:`Server`)."""

    def __init__(self, target: Path, folder: Path):
        from sgjax.editor.server import make_server
        from sgjax.editor.session import EditorSession

        self.folder, self.target = folder, target
        self.httpd = make_server(EditorSession.open(str(target)), port=0)
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)
        self.thread.start()
        self.url = self.httpd.url

    def stop(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()


class Launcher:
    """A server per map of the parametrized open-and-save tests, on a copy of the map in its
    own folder."""

    def __init__(self, base: Path):
        self.base = base

    def take(self, key: tuple[str, str]) -> InProcessServer:
        kind, name = key
        folder = self.base / f"{kind}-{name}"
        folder.mkdir()
        if kind == "shipped":
            target = folder / f"{name}.json"
            shutil.copyfile(REPO / "maps" / f"{name}.json", target)
        else:
            target = folder / name
            shutil.copytree(SG2MAPS / name, target)
        return InProcessServer(target, folder)


@pytest.fixture(scope="module")
def launcher(tmp_path_factory):
    return Launcher(tmp_path_factory.mktemp("maps"))


# ------------------------------------------------------------------ the browser


@pytest.fixture(scope="module")
def browser():
    if webdriver is None:
        pytest.skip(f"selenium is not installed ({MISSING})")
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    driver_path = shutil.which("chromedriver")
    if chromium is None or driver_path is None:
        pytest.skip(f"chromium or chromedriver is missing ({MISSING})")
    options = Options()
    options.binary_location = chromium  # with the driver's path: no Selenium Manager
    for flag in ("--headless=new", "--window-size=1280,800", "--no-sandbox",
                 "--disable-dev-shm-usage", "--disable-gpu", "--force-device-scale-factor=1",
                 "--disable-extensions", "--no-first-run"):
        options.add_argument(flag)
    try:
        driver = webdriver.Chrome(service=Service(driver_path), options=options)
    except WebDriverException as err:
        pytest.skip(f"headless Chromium did not start: {err.msg} ({MISSING})")
    # 1280 x 800 of page (the window's frame, if any, around it)
    frame_w, frame_h = js(driver, "return [window.outerWidth - window.innerWidth, "
                                  "window.outerHeight - window.innerHeight]")
    driver.set_window_size(1280 + frame_w, 800 + frame_h)
    try:
        yield driver
    finally:
        driver.quit()


def js(driver, script: str, *args):
    return driver.execute_script(script, *args)


def wait_for(driver, condition, timeout: float = WAIT, what: str = "the page"):
    try:
        return WebDriverWait(driver, timeout, poll_frequency=0.05).until(lambda d: condition(d))
    except TimeoutException:
        status = js(driver, "return document.getElementById('status').textContent + ' | ' + "
                            "document.getElementById('message').textContent")
        raise AssertionError(f"timed out waiting for {what}; status: {status}") from None


def idle(driver, timeout: float = WAIT) -> None:
    """Wait until the page has no check, save, play or routes request pending."""
    wait_for(driver, lambda d: js(d, "return window.sgjaxEditor.ready && "
                                     "!window.sgjaxEditor.busy()"), timeout, "an idle page")


def open_page(driver, url: str, restore: bool | None = False) -> None:
    """Load the page and wait until it is ready; answer the restore dialog if it shows."""
    driver.get(url)
    wait_for(driver, lambda d: js(d, "return !!(window.sgjaxEditor && window.sgjaxEditor.ready)"),
             what="the page to load")
    dialog = driver.find_element(By.ID, "restore-dialog")
    if dialog.is_displayed() and restore is not None:
        driver.find_element(By.ID, "restore-yes" if restore else "restore-no").click()
    idle(driver)


def get_map(driver) -> dict:
    return js(driver, "return window.sgjaxEditor.getMap()")


def canvas_offset(driver, x: float, y: float) -> tuple[int, int]:
    """ActionChains offsets (from the canvas's centre) of world point (x, y)."""
    px, py, w, h = js(driver, "const c = document.getElementById('canvas');"
                              "const r = c.getBoundingClientRect();"
                              "const e = window.sgjaxEditor;"
                              "return [...e.worldToScreen(arguments[0], arguments[1]),"
                              " r.width, r.height];", x, y)
    assert 2 <= px <= w - 2 and 2 <= py <= h - 2, f"({x}, {y}) is off the canvas: ({px}, {py})"
    return round(px - w / 2), round(py - h / 2)


def actions(driver) -> ActionChains:
    """An action chain whose pointer moves take no time (Selenium's default is 250 ms each)."""
    return ActionChains(driver, duration=0)


def click_at(driver, x: float, y: float, double: bool = False) -> None:
    canvas = driver.find_element(By.ID, "canvas")
    chain = actions(driver).move_to_element_with_offset(canvas, *canvas_offset(driver, x, y))
    (chain.double_click() if double else chain.click()).perform()


def drag(driver, start: tuple[float, float], end: tuple[float, float], steps: int = 4) -> None:
    canvas = driver.find_element(By.ID, "canvas")
    x0, y0 = canvas_offset(driver, *start)
    x1, y1 = canvas_offset(driver, *end)
    chain = actions(driver).move_to_element_with_offset(canvas, x0, y0).click_and_hold()
    done = (0, 0)
    for k in range(1, steps + 1):
        target = (round((x1 - x0) * k / steps), round((y1 - y0) * k / steps))
        chain.move_by_offset(target[0] - done[0], target[1] - done[1])
        done = target
    chain.release().perform()


def keys(driver, *sequence) -> None:
    actions(driver).send_keys(*sequence).perform()


def chord(driver, *modifiers_and_key) -> None:
    """Press a key with modifiers held (Ctrl+Z: ``chord(driver, Keys.CONTROL, "z")``)."""
    *modifiers, key = modifiers_and_key
    chain = actions(driver)
    for m in modifiers:
        chain.key_down(m)
    chain.send_keys(key)
    for m in reversed(modifiers):
        chain.key_up(m)
    chain.perform()


def tool(driver, key: str) -> None:
    """Pick a tool by its keyboard shortcut (focus off any input first)."""
    js(driver, "document.activeElement && document.activeElement.blur()")
    keys(driver, key)


def set_field(driver, element_id: str, value) -> None:
    """Type ``value`` into a field and leave it (its input and change events fire)."""
    field = driver.find_element(By.ID, element_id)
    field.send_keys(Keys.CONTROL, "a")
    field.send_keys(Keys.DELETE)
    field.send_keys(str(value))
    field.send_keys(Keys.TAB)


def text(driver, element_id: str) -> str:
    return driver.find_element(By.ID, element_id).text


def save(driver, overwrite: bool | None = None) -> str:
    """Press Save (confirming or refusing the overwrite dialog when ``overwrite`` is given) and
    return the message once the save has answered."""
    js(driver, "document.getElementById('message').textContent = ''")
    driver.find_element(By.ID, "save").click()
    if overwrite is not None:
        dialog = driver.find_element(By.ID, "overwrite-dialog")
        wait_for(driver, lambda d: dialog.is_displayed(), what="the overwrite dialog")
        driver.find_element(By.ID, "overwrite-yes" if overwrite else "overwrite-no").click()
    wait_for(driver, lambda d: text(d, "message").startswith(("saved", "not saved")),
             what="the save to answer")
    return text(driver, "message")


def screenshot(driver, folder: Path, name: str, docs: bool = False) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.png"
    driver.save_screenshot(str(path))
    if docs and os.environ.get("SGJAX_EDITOR_SCREENSHOTS") == "docs":
        DOCS_IMG.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(path, DOCS_IMG / f"editor_{name}.png")
    return path


SCALE = ("const e = window.sgjaxEditor; "
         "return e.worldToScreen(1, 0)[0] - e.worldToScreen(0, 0)[0]")  # px per metre


def status_counts(driver) -> str:
    return text(driver, "status")


# ------------------------------------------------------------------ shared servers


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    """A server on a new, empty map in a folder of its own (``root``)."""
    base = tmp_path_factory.mktemp("scratch")
    root = base / "root"
    root.mkdir()
    with server(["--new", "scratch", "--root", str(root)], base) as s:
        s.root = root
        yield s


@pytest.fixture(scope="module")
def doorway(tmp_path_factory):
    """A server on a copy of the shipped doorway map."""
    folder = tmp_path_factory.mktemp("doorway")
    shutil.copyfile(REPO / "maps" / "doorway.json", folder / "doorway.json")
    with server([str(folder / "doorway.json")], folder) as s:
        s.folder = folder
        yield s


# ------------------------------------------------------------------ the tests


LEFT_STARTS = [(-4.0, -2.0), (-4.0, -1.0), (-4.0, 1.0), (-4.0, 2.0)]
RIGHT_GOALS = [(4.0, -2.0), (4.0, -1.0), (4.0, 1.0), (4.0, 2.0)]
HUBS = [(-2.0, 0.0), (0.0, 0.0), (2.0, 0.0)]  # left hub, in the door, right hub
# two 5.5 m x 6 m rooms joined by a 1 m wide, 1 m long door, drawn as one chain of walls
OUTLINE = [(-0.5, 0.5), (-0.5, 3), (-6, 3), (-6, -3), (-0.5, -3), (-0.5, -0.5), (0.5, -0.5),
           (0.5, -3), (6, -3), (6, 3), (0.5, 3), (0.5, 0.5), (-0.5, 0.5)]


def test_draw_a_doorway_from_an_empty_map(browser, tmp_path):
    import jax
    import numpy as np

    import sgjax

    shots = tmp_path / "screenshots"
    with server(["--new", "doorgame", "--root", str(tmp_path)], tmp_path) as s:
        open_page(browser, s.url)
        assert browser.find_element(By.ID, "filename").get_attribute("value") == "doorgame.json"
        for key, value in zip(("xmin", "ymin", "xmax", "ymax"), (-6.5, -3.5, 6.5, 3.5),
                              strict=True):
            set_field(browser, f"bounds-{key}", value)
        browser.find_element(By.ID, "fit").click()

        tool(browser, "w")
        for x, y in OUTLINE:
            click_at(browser, x, y)
        keys(browser, Keys.ESCAPE)
        walls = get_map(browser)["walls"]
        assert len(walls) == len(OUTLINE) - 1
        assert walls[0][:2] == [-0.5, 0.5] and walls[-1][2:] == [-0.5, 0.5]  # closed
        for a, b in zip(walls, walls[1:], strict=False):
            assert a[2:] == b[:2]  # every corner joined
        screenshot(browser, shots, "walls")

        tool(browser, "n")
        for x, y in LEFT_STARTS + HUBS + RIGHT_GOALS:
            click_at(browser, x, y)
        nodes = get_map(browser)["nodes"]
        assert [n["id"] for n in nodes] == list(range(11))
        assert [tuple(n["position"]) for n in nodes] == LEFT_STARTS + HUBS + RIGHT_GOALS

        tool(browser, "e")
        points = LEFT_STARTS + HUBS + RIGHT_GOALS
        edges = [[0, 4], [1, 4], [2, 4], [3, 4], [4, 5], [5, 6], [6, 7], [6, 8], [6, 9], [6, 10]]
        for a, b in edges:
            click_at(browser, *points[a])
            click_at(browser, *points[b])
        assert get_map(browser)["edges"] == edges

        tool(browser, "g")
        assert "starts" in text(browser, "group-phase")
        for p in LEFT_STARTS:
            click_at(browser, *p)
        browser.find_element(By.ID, "group-phase").click()
        assert "goals" in text(browser, "group-phase")
        for p in RIGHT_GOALS:
            click_at(browser, *p)
        assert get_map(browser)["groups"] == [{"starts": [0, 1, 2, 3], "goals": [7, 8, 9, 10]}]

        set_field(browser, "zone-name", "door")
        tool(browser, "z")
        drag(browser, (-1, -1), (1, 1))
        assert get_map(browser)["zones"] == [{"name": "door", "rect": [-1, -1, 1, 1]}]

        browser.find_element(By.ID, "bounds-fit").click()  # content + 1 m
        assert get_map(browser)["bounds"] == [-7, -4, 7, 4]
        set_field(browser, "map-description", "two rooms and a door, drawn in the browser")
        idle(browser)
        assert status_counts(browser).startswith("0 errors"), js(
            browser, "return window.sgjaxEditor.problems()")
        assert not browser.find_elements(By.CSS_SELECTOR, "li.problem[data-severity=error]")
        browser.find_element(By.ID, "fit").click()
        tool(browser, "v")
        keys(browser, Keys.ESCAPE)  # nothing selected
        screenshot(browser, shots, "doorway", docs=True)

        browser.find_element(By.ID, "routes").click()
        idle(browser)
        routes = js(browser, "return window.sgjaxEditor.routes()")
        assert routes["pairs"] == 16 and len(routes["routes"]) == 16
        assert not any(r["tie"] for r in routes["routes"])
        screenshot(browser, shots, "routes", docs=True)
        browser.find_element(By.ID, "routes").click()

        # play 64 episodes of 4 robots before saving: the metrics, and episode 0 animated
        browser.find_element(By.CSS_SELECTOR, "#play-policy option[value=only_local]").click()
        set_field(browser, "play-robots", 4)
        set_field(browser, "play-episodes", 64)
        browser.find_element(By.ID, "play").click()
        assert text(browser, "play-result").startswith("running...")
        wait_for(browser, lambda d: "team_success" in text(d, "play-result"), timeout=300,
                 what="the play result")
        assert "4 robots, 64 episodes" in text(browser, "play-result")
        row = browser.find_element(By.CSS_SELECTOR, "#play-result tr[data-metric=team_success]")
        mean, std = (float(v) for v in row.find_elements(By.TAG_NAME, "td")[1].text.split("±"))
        assert 0 <= mean <= 1 and std >= 0
        assert js(browser, "return !window.sgjaxEditor.busy()")
        time.sleep(1.5)  # a second and a half of the animation
        screenshot(browser, shots, "play", docs=True)
        browser.find_element(By.ID, "play-stop").click()

        message = save(browser)
        saved = tmp_path / "doorgame.json"
        assert message == f"saved {saved.resolve()}"
        drawn = get_map(browser)

    assert json.loads(saved.read_text()) == drawn
    spec = sgjax.maps.load(saved)
    assert spec.name == "doorgame" and len(spec.walls) == 12 and spec.num_nodes == 11
    assert [z.name for z in spec.zones] == ["door"]
    env, params = sgjax.make(saved)  # the default 4 robots
    key = jax.random.key(0)
    obs, state = env.reset(key, params)
    for _ in range(3):
        key, sub = jax.random.split(key)
        obs, state, reward, terminated, truncated, info = env.step(
            sub, state, state.held_action, params)
    assert np.all(np.isfinite(np.asarray(obs))) and np.all(np.isfinite(np.asarray(reward)))
    # the saved file is a scenario for sgjax evaluate
    from sgjax.command import main as sgjax_main

    sgjax_main(["evaluate", "--scenario", str(saved), "--policy", "only_local",
                "--num-agents", "4", "--episodes", "4", "--time-limit", "30",
                "--out", str(tmp_path / "eval")])
    assert "| doorgame |" in (tmp_path / "eval" / "table.md").read_text() or (
        str(saved) in (tmp_path / "eval" / "table.md").read_text())


def test_an_invalid_node_shows_its_error_at_the_node(browser, doorway, tmp_path):
    open_page(browser, doorway.url)
    assert status_counts(browser) == "0 errors, 0 warnings"
    count = len(get_map(browser)["nodes"])
    browser.find_element(By.ID, "fit").click()

    # the wheel zooms about the cursor: the world point under it stays put
    canvas = browser.find_element(By.ID, "canvas")
    scale = js(browser, SCALE)
    before = js(browser, "return window.sgjaxEditor.worldToScreen(-9, 3)")
    ox, oy = canvas_offset(browser, -9, 3)
    actions(browser).scroll_from_origin(ScrollOrigin.from_element(canvas, ox, oy), 0, -300
                                             ).perform()
    wait_for(browser, lambda d: js(d, SCALE) > 1.2 * scale, what="the zoom")
    after = js(browser, "return window.sgjaxEditor.worldToScreen(-9, 3)")
    assert abs(after[0] - before[0]) < 2 and abs(after[1] - before[1]) < 2

    set_field(browser, "grid", "0.1")
    tool(browser, "n")
    click_at(browser, -9.9, 3.0)  # 0.1 m from the left wall (x = -10): robots need 0.25 m
    node = get_map(browser)["nodes"][count]
    assert node["position"] == pytest.approx([-9.9, 3.0])
    idle(browser)
    path = f"$.nodes[{count}]"
    problem = wait_for(browser, lambda d: [
        li for li in d.find_elements(By.CSS_SELECTOR, "li.problem[data-severity=error]")
        if li.get_attribute("data-path") == path], what=f"an error at {path}")[0]
    assert problem.text.startswith(problem.get_attribute("data-path"))
    assert status_counts(browser).startswith("1 error,")
    assert any(p["element"] == {"kind": "node", "index": count}
               for p in js(browser, "return window.sgjaxEditor.problems()"))
    # clicking the problem centres the view on it
    tool(browser, "v")
    drag(browser, (-9, 1), (-8, 2))  # pan away first (select tool on empty space)
    assert abs(js(browser, "return window.sgjaxEditor.worldToScreen(-9, 3)[0]") - after[0]
               - js(browser, SCALE)) < 2
    problem.click()
    px, py, w, h = js(browser, "const r = document.getElementById('canvas')"
                               ".getBoundingClientRect();"
                               "return [...window.sgjaxEditor.worldToScreen(-9.9, 3), "
                               "r.width, r.height]")
    assert abs(px - w / 2) < 15 and abs(py - h / 2) < 15
    screenshot(browser, tmp_path / "screenshots", "problem", docs=True)
    # saving refuses a map with errors (422): the message says why
    message = save(browser)
    assert message.startswith("not saved") and "error" in message
    assert json.loads((doorway.folder / "doorway.json").read_text()) == json.loads(
        (REPO / "maps" / "doorway.json").read_text())


@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_a_shipped_map_opens_and_saves_back_equal(browser, launcher, tmp_path, path):
    s = launcher.take(("shipped", path.stem))  # its own copy of the map, in a folder of its own
    copy = s.target
    try:
        open_page(browser, s.url)
        assert status_counts(browser).startswith("0 errors")
        assert get_map(browser) == json.loads(path.read_text())
        if path.stem == "office":
            screenshot(browser, tmp_path / "screenshots", "office", docs=True)
        message = save(browser)
    finally:
        s.stop()
    assert message == f"saved {copy.resolve()}"
    assert json.loads(copy.read_text()) == json.loads(path.read_text())
    assert copy.read_bytes() == path.read_bytes()
    assert sorted(p.name for p in s.folder.iterdir() if p.suffix != ".log") == [path.name]


def test_a_save_outside_the_root_is_refused(browser, scratch):
    open_page(browser, scratch.url)
    outside = scratch.root.parent
    before = sorted(p.name for p in outside.iterdir())
    for name in ("../evil.json", str(outside / "evil.json")):
        set_field(browser, "filename", name)
        message = save(browser)
        assert message.startswith("not saved") and "refused" in message, message
    assert sorted(p.name for p in outside.iterdir()) == before
    assert not (outside / "evil.json").exists()
    assert not list(scratch.root.glob("*.json"))


def test_undo_redo_and_autosave(browser, scratch, tmp_path):
    open_page(browser, scratch.url)
    js(browser, "window.sgjaxEditor.setMap(arguments[0])",
       {"name": "scratch", "description": "", "bounds": [-5, -5, 5, 5], "walls": [],
        "nodes": [], "edges": [], "groups": []})
    browser.find_element(By.ID, "fit").click()
    tool(browser, "w")
    click_at(browser, -2, 1)
    click_at(browser, 2, 1, double=True)  # the double click ends the chain
    click_at(browser, 3, -3)  # a new chain starts: no wall yet
    keys(browser, Keys.ESCAPE)
    assert get_map(browser)["walls"] == [[-2, 1, 2, 1]]
    browser.find_element(By.ID, "undo").click()
    assert get_map(browser)["walls"] == []
    browser.find_element(By.ID, "redo").click()
    assert get_map(browser)["walls"] == [[-2, 1, 2, 1]]
    js(browser, "document.activeElement.blur()")
    chord(browser, Keys.CONTROL, "z")
    assert get_map(browser)["walls"] == []
    chord(browser, Keys.CONTROL, Keys.SHIFT, "z")
    assert get_map(browser)["walls"] == [[-2, 1, 2, 1]]
    chord(browser, Keys.CONTROL, "z")
    chord(browser, Keys.CONTROL, "y")
    assert get_map(browser)["walls"] == [[-2, 1, 2, 1]]
    idle(browser)
    screenshot(browser, tmp_path / "screenshots", "undo")
    # the autosave (2 s after the last change) is offered back on the next load
    autosave = scratch.root / ".scratch.json.autosave"
    wait_for(browser, lambda d: autosave.exists(), timeout=10, what="the autosave")
    assert json.loads(autosave.read_text())["walls"] == [[-2, 1, 2, 1]]
    open_page(browser, scratch.url, restore=None)
    assert browser.find_element(By.ID, "restore-dialog").is_displayed()
    browser.find_element(By.ID, "restore-yes").click()
    idle(browser)
    assert get_map(browser)["walls"] == [[-2, 1, 2, 1]]
    browser.find_element(By.ID, "undo").click()  # back to the file's map
    assert get_map(browser)["walls"] == []


def test_split_drag_and_delete(browser, scratch, tmp_path):
    open_page(browser, scratch.url)
    js(browser, "window.sgjaxEditor.setMap(arguments[0])", {
        "name": "scratch", "description": "", "bounds": [-1, -1, 6, 5],
        "walls": [[0, 0, 4, 0], [4, 0, 4, 3]],
        "nodes": [{"id": 0, "position": [1, 2]}, {"id": 1, "position": [3, 2]},
                  {"id": 2, "position": [2, 1]}],
        "edges": [[0, 1], [1, 2]],
        "groups": [{"starts": [0], "goals": [1]}, {"starts": [2], "goals": []}],
        "routes": [[0, 2, 1]]})
    browser.find_element(By.ID, "fit").click()
    tool(browser, "s")
    click_at(browser, 2, 0)
    assert get_map(browser)["walls"] == [[0, 0, 2, 0], [2, 0, 4, 0], [4, 0, 4, 3]]
    tool(browser, "v")
    drag(browser, (4, 0), (5, -0.5))  # the corner: both walls' ends move together
    assert get_map(browser)["walls"] == [[0, 0, 2, 0], [2, 0, 5, -0.5], [5, -0.5, 4, 3]]
    drag(browser, (2, 1), (2, 1.5))  # a node
    assert get_map(browser)["nodes"][2]["position"] == [2, 1.5]
    tool(browser, "d")
    click_at(browser, 2, 1.5)  # node 2: its edge, its group (left empty) and route waypoint go
    edited = get_map(browser)
    assert [n["id"] for n in edited["nodes"]] == [0, 1]
    assert edited["edges"] == [[0, 1]]
    assert edited["groups"] == [{"starts": [0], "goals": [1]}]
    assert edited["routes"] == [[0, 1]]
    click_at(browser, 1, 0)  # a wall
    assert len(get_map(browser)["walls"]) == 2
    tool(browser, "v")
    click_at(browser, 2, 2)  # select the edge 0-1, then the Delete key
    keys(browser, Keys.DELETE)
    assert get_map(browser)["edges"] == []
    # a new robot group, then a pedestrian group made by the group tool
    browser.find_element(By.ID, "group-new").click()
    assert get_map(browser)["groups"] == [{"starts": [0], "goals": [1]},
                                          {"starts": [], "goals": []}]
    assert Select(browser.find_element(By.ID, "group-index")).first_selected_option.get_attribute(
        "value") == "1"
    Select(browser.find_element(By.ID, "group-kind")).select_by_value("pedestrian_groups")
    tool(browser, "g")
    click_at(browser, 1, 2)  # node 0: a pedestrian start
    browser.find_element(By.ID, "group-phase").click()
    click_at(browser, 3, 2)  # node 1: a pedestrian goal
    assert get_map(browser)["pedestrian_groups"] == [{"starts": [0], "goals": [1]}]
    tool(browser, "v")
    # Space + drag and a middle-button drag pan, even from on top of a wall
    walls = get_map(browser)["walls"]
    canvas = browser.find_element(By.ID, "canvas")
    for how in ("space", "middle"):
        before = js(browser, "return window.sgjaxEditor.worldToScreen(0, 0)")
        x0, y0 = canvas_offset(browser, 4.5, 1.25)  # the middle of a wall
        if how == "space":
            actions(browser).move_to_element_with_offset(canvas, x0, y0).key_down(Keys.SPACE) \
                .click_and_hold().move_by_offset(20, 10).move_by_offset(20, 15).release() \
                .key_up(Keys.SPACE).perform()
        else:
            builder = ActionBuilder(browser, duration=0)
            builder.pointer_action.move_to(canvas, x0, y0).pointer_down(MouseButton.MIDDLE) \
                .move_by(20, 10).move_by(20, 15).pointer_up(MouseButton.MIDDLE)
            builder.perform()
        after = js(browser, "return window.sgjaxEditor.worldToScreen(0, 0)")
        assert after == pytest.approx([before[0] + 40, before[1] + 25], abs=1.5), how
    assert get_map(browser)["walls"] == walls
    idle(browser)
    screenshot(browser, tmp_path / "screenshots", "edited")


@pytest.mark.parametrize("name", SG2_FOLDERS or ["(none)"])
def test_a_socialgym_folder_opens_and_saves_its_import(browser, launcher, tmp_path, name):
    if not SG2_FOLDERS:
        require(SG2MAPS / "GDC1", "SocialGym 2.0's map folders")
    from sgjax.maps import import_socialgym

    s = launcher.take(("sg2", name))  # `sgjax edit FOLDER` on a copy of the folder
    folder = s.target
    try:
        open_page(browser, s.url)
        assert status_counts(browser).startswith("0 errors"), js(
            browser, "return window.sgjaxEditor.problems()")
        if name == "GDC1":
            screenshot(browser, tmp_path / "screenshots", "socialgym_gdc1", docs=True)
        message = save(browser)
    finally:
        s.stop()
    saved = folder / f"{name}.json"
    assert message == f"saved {saved.resolve()}"
    assert json.loads(saved.read_text()) == import_socialgym(folder).to_json()


# ------------------------------------------------------------------ safety and friction


def test_a_page_from_another_origin_cannot_write_through_the_editor(browser, doorway, tmp_path):
    """The cross-origin request of the security report, replayed from a real page on another
    port: no-cors POSTs with a text/plain body to save, autosave and play, and a CORS request
    guessing at the token. Nothing is written, deleted or switched."""
    import http.server

    open_page(browser, doorway.url)
    tool(browser, "n")
    click_at(browser, 3.0, 0.5)  # an edit, so that an autosave of the open map exists
    autosave = doorway.folder / ".doorway.json.autosave"
    wait_for(browser, lambda d: autosave.exists(), timeout=10, what="the autosave")
    before = {p.name: p.read_bytes() for p in doorway.folder.iterdir() if p.suffix != ".log"}
    editor = doorway.url.split("/?token=")[0]
    attack = tmp_path / "attack"
    attack.mkdir()
    body = json.dumps({"map": json.loads((REPO / "maps" / "doorway.json").read_text()),
                       "file": "evil.json", "overwrite": True})
    (attack / "index.html").write_text(f"""<!DOCTYPE html><html><body><script>
const target = {json.dumps(editor)};
const body = {json.dumps(body)};
const simple = {{method: "POST", mode: "no-cors", headers: {{"Content-Type": "text/plain"}}, body}};
window.results = [];
Promise.allSettled([
  fetch(target + "/api/save", simple), fetch(target + "/api/autosave", simple),
  fetch(target + "/api/play", simple),
  fetch(target + "/api/save", {{method: "POST", headers: {{"Content-Type": "application/json",
    "X-Sgjax-Token": "guess"}}, body}}),
  fetch(target + "/api/session").then((r) => r.text()),
]).then((all) => {{ window.results = all.map((r) => r.status); window.done = true; }});
</script></body></html>""")
    handler = type("Quiet", (http.server.SimpleHTTPRequestHandler,),
                   {"log_message": lambda *args: None})
    evil = http.server.ThreadingHTTPServer(
        ("127.0.0.1", 0), lambda *a: handler(*a, directory=str(attack)))
    threading.Thread(target=evil.serve_forever, daemon=True).start()
    try:
        browser.get(f"http://127.0.0.1:{evil.server_address[1]}/index.html")
        wait_for(browser, lambda d: js(d, "return window.done === true"), timeout=30,
                 what="the other page's requests")
        # the reads are opaque or refused: a no-cors answer is hidden, CORS is never granted
        assert "fulfilled" not in js(browser, "return window.results")[3:]
    finally:
        evil.shutdown()
        evil.server_close()
    time.sleep(0.5)
    after = {p.name: p.read_bytes() for p in doorway.folder.iterdir() if p.suffix != ".log"}
    assert after == before
    open_page(browser, doorway.url, restore=None)  # the editor still edits doorway.json
    assert browser.find_element(By.ID, "filename").get_attribute("value") == "doorway.json"
    browser.find_element(By.ID, "restore-no").click()
    autosave.unlink()
    # and the page without its token says what to open
    browser.get(editor + "/")
    wait_for(browser, lambda d: "token" in text(d, "message"), timeout=20,
             what="the missing-token message")
    # DNS rebinding: another name for 127.0.0.1 (Chromium resolves *.localhost to it) is refused
    # even with the token
    port = editor.rsplit(":", 1)[1]
    browser.get(f"http://rebound.localhost:{port}/?token={doorway.token}")
    assert "is not this editor's address" in browser.find_element(By.TAG_NAME, "body").text
    assert not (doorway.folder / "evil.json").exists()


def _peak_rss_mb(pid: int) -> float:
    """The peak resident memory (MB) of process ``pid`` so far (Linux: VmHWM)."""
    line = next(v for v in Path(f"/proc/{pid}/status").read_text().splitlines()
                if v.startswith("VmHWM:"))
    return int(line.split()[1]) / 1024


def test_a_dense_map_and_its_autosave_open_within_a_memory_bound(browser, tmp_path):
    """The security report's dense map: 200,000 short walls packed into one room, opened in the
    editor with an autosave of it to restore (which took the server to 24 GB before). The page
    shows its problems, the server's memory stays bounded and it answers on."""
    from dense_maps import packed_room

    dense = packed_room(200_000)
    (tmp_path / "packed.json").write_text(json.dumps(dense))
    dense["walls"] = dense["walls"][:150_000]
    (tmp_path / ".packed.json.autosave").write_text(json.dumps(dense))
    with server([str(tmp_path / "packed.json")], tmp_path) as s:
        url = s.url
        idle_mb = _peak_rss_mb(s.process.pid)
        open_page(browser, url, restore=True)
        assert len(get_map(browser)["walls"]) == 150_000  # the autosave, restored
        assert status_counts(browser).startswith("2 errors"), status_counts(browser)
        peak_mb = _peak_rss_mb(s.process.pid)
        assert peak_mb - idle_mb < 1500, f"{peak_mb:.0f} MB at peak, {idle_mb:.0f} MB idle"
        assert s.process.poll() is None


def test_fields_edit_only_what_they_show_and_give_the_keys_back(browser, scratch, tmp_path):
    open_page(browser, scratch.url)
    js(browser, "window.sgjaxEditor.setMap(arguments[0])",
       {"name": "scratch", "description": "", "bounds": [-6, -4, 6, 4],
        "walls": [[-5, 3, 0, 3], [0, 3, 5, 3]], "nodes": [], "edges": [], "groups": []})
    browser.find_element(By.ID, "fit").click()
    # a zone's name field names new zones only; the drawn one is renamed under Selection
    set_field(browser, "zone-name", "left door")
    tool(browser, "z")
    drag(browser, (-4, -1), (-3, 1))
    set_field(browser, "zone-name", "right door")  # zone 0 is still selected
    assert [z["name"] for z in get_map(browser)["zones"]] == ["left door"]
    tool(browser, "z")
    drag(browser, (3, -1), (4, 1))
    assert [z["name"] for z in get_map(browser)["zones"]] == ["left door", "right door"]
    tool(browser, "v")
    click_at(browser, -3.5, 0)
    assert browser.find_element(By.ID, "sel-name").get_attribute("value") == "left door"
    set_field(browser, "sel-name", "west door")
    set_field(browser, "sel-x-min", -4.25)
    zones = get_map(browser)["zones"]
    assert zones[0] == {"name": "west door", "rect": [-4.25, -1, -3, 1]}
    assert zones[1]["name"] == "right door"
    # exact positions: a node right after placing it, and a wall end (its joined end moves too)
    tool(browser, "n")
    click_at(browser, -2, 0)
    set_field(browser, "sel-x", 1.75)
    set_field(browser, "sel-y", "-0.3")
    assert get_map(browser)["nodes"] == [{"id": 0, "position": [1.75, -0.3]}]
    tool(browser, "v")
    click_at(browser, -2.5, 3)  # wall 0
    set_field(browser, "sel-x2", 0.4)
    set_field(browser, "sel-y2", 2.9)
    assert get_map(browser)["walls"] == [[-5, 3, 0.4, 2.9], [0.4, 2.9, 5, 3]]
    set_field(browser, "sel-y1", "abc")  # refused: said, and the map is unchanged
    assert "expected a number" in text(browser, "message")
    assert get_map(browser)["walls"][0] == [-5, 3, 0.4, 2.9]
    # Escape and Enter in a field hand the keys back to the map
    field = browser.find_element(By.ID, "zone-name")
    field.click()
    keys(browser, Keys.ESCAPE)
    assert js(browser, "return document.activeElement.id") == "canvas"
    keys(browser, "n")
    assert "active" in browser.find_element(By.CSS_SELECTOR, "[data-tool=node]").get_attribute(
        "class")
    grid = browser.find_element(By.ID, "grid")
    grid.click()
    grid.send_keys(Keys.CONTROL, "a")
    grid.send_keys("0.25", Keys.ENTER)
    assert js(browser, "return document.activeElement.id") == "canvas"
    keys(browser, "e")
    assert "active" in browser.find_element(By.CSS_SELECTOR, "[data-tool=edge]").get_attribute(
        "class")
    screenshot(browser, tmp_path / "screenshots", "fields")


def test_runs_of_edges_group_boxes_and_ids_as_loaded(browser, scratch, tmp_path):
    open_page(browser, scratch.url)
    row = [(-4.0, 0.0), (-2.0, 0.0), (0.0, 0.0), (2.0, 0.0), (4.0, 0.0)]
    ids = [0, 1, 2, 20, 21]  # a gap in the ids, as a file may have
    js(browser, "window.sgjaxEditor.setMap(arguments[0])",
       {"name": "scratch", "description": "", "bounds": [-5, -3, 5, 3], "walls": [],
        "nodes": [{"id": i, "position": list(p)} for i, p in zip(ids, row, strict=True)],
        "edges": [], "groups": []})
    browser.find_element(By.ID, "fit").click()
    # one drag through the row joins it in order: one undo step takes the run back
    tool(browser, "e")
    canvas = browser.find_element(By.ID, "canvas")
    chain = actions(browser).move_to_element_with_offset(canvas, *canvas_offset(browser, *row[0]))
    chain.click_and_hold()
    for p in row[1:]:  # the pointer passes over each node in turn
        chain.move_to_element_with_offset(canvas, *canvas_offset(browser, *p))
    chain.release().perform()
    assert get_map(browser)["edges"] == [[0, 1], [1, 2], [2, 20], [20, 21]]
    browser.find_element(By.ID, "undo").click()
    assert get_map(browser)["edges"] == []
    browser.find_element(By.ID, "redo").click()
    # clicks still join one pair
    click_at(browser, *row[0])
    click_at(browser, *row[4])
    assert get_map(browser)["edges"][-1] == [0, 21]
    # a box adds every node in it to the group's current phase
    tool(browser, "g")
    drag(browser, (-4.5, -1), (-1.5, 1))
    browser.find_element(By.ID, "group-phase").click()
    drag(browser, (1.5, -1), (4.5, 1))
    assert get_map(browser)["groups"] == [{"starts": [0, 1], "goals": [20, 21]}]
    # ids stay as loaded: a new node takes the largest + 1, and an id can be set
    tool(browser, "n")
    click_at(browser, 0, 2)
    assert [n["id"] for n in get_map(browser)["nodes"]] == [0, 1, 2, 20, 21, 22]
    tool(browser, "v")
    click_at(browser, 2, 0)  # node 20
    set_field(browser, "sel-id", 7)
    set_field(browser, "sel-id", 21)  # taken: refused
    assert "taken" in text(browser, "message")
    edited = get_map(browser)
    assert [n["id"] for n in edited["nodes"]] == [0, 1, 2, 7, 21, 22]
    assert edited["edges"] == [[0, 1], [1, 2], [2, 7], [7, 21], [0, 21]]
    assert edited["groups"] == [{"starts": [0, 1], "goals": [7, 21]}]
    # saving the file being edited twice asks nothing
    assert save(browser).startswith("saved")
    tool(browser, "n")
    click_at(browser, 0, -2)
    assert save(browser).startswith("saved")
    saved = json.loads((scratch.root / "scratch.json").read_text())
    assert [n["id"] for n in saved["nodes"]] == [0, 1, 2, 7, 21, 22, 23]
    (scratch.root / "scratch.json").unlink()
    screenshot(browser, tmp_path / "screenshots", "runs")


def test_the_autosave_message_clears_and_stop_cancels_a_batch(browser, doorway, tmp_path):
    open_page(browser, doorway.url)
    autosave = doorway.folder / ".doorway.json.autosave"
    autosave.mkdir()  # an autosave cannot be written while a folder has its name
    try:
        tool(browser, "n")
        click_at(browser, 3.0, 0.5)
        wait_for(browser, lambda d: text(d, "message").startswith("autosave failed"),
                 timeout=15, what="the autosave failure")
    finally:
        autosave.rmdir()
    click_at(browser, 3.0, -0.5)
    wait_for(browser, lambda d: text(d, "message") == "autosaved: the server answers again",
             timeout=15, what="the autosave message to clear")
    assert autosave.is_file()
    # Stop ends a batch of 1,024 episodes after its current part of 64
    set_field(browser, "play-robots", 4)
    set_field(browser, "play-episodes", 1024)
    browser.find_element(By.ID, "play").click()
    wait_for(browser, lambda d: text(d, "play-result").startswith("running"), timeout=10,
             what="the batch to start")
    browser.find_element(By.ID, "play-stop").click()
    wait_for(browser, lambda d: text(d, "play-result").startswith("stopped after"),
             timeout=120, what="the batch to stop")
    assert "of 16 part(s)" in text(browser, "play-result")
    assert int(text(browser, "play-result").split("stopped after ")[1].split()[0]) < 16
    assert browser.find_element(By.ID, "play").is_enabled()
    set_field(browser, "play-episodes", 8)  # the next batch plays
    browser.find_element(By.ID, "play").click()
    wait_for(browser, lambda d: "team_success" in text(d, "play-result"), timeout=120,
             what="the next batch")
    autosave.unlink()


def test_generate_draws_a_family_world_to_edit_and_save(browser, scratch, tmp_path):
    from sgjax.maps.check import check_map

    open_page(browser, scratch.url, restore=False)
    js(browser, "window.sgjaxEditor.setMap(arguments[0])",
       {"name": "scratch", "description": "", "bounds": [-5, -5, 5, 5], "walls": [[0, 0, 1, 0]],
        "nodes": [], "edges": [], "groups": []})
    Select(browser.find_element(By.ID, "generate-family")).select_by_value("floorplan")
    fields = browser.find_elements(By.CSS_SELECTOR, "#generate-parameters input")
    names = {f.get_attribute("data-parameter") for f in fields}
    assert {"room_size", "corridor"} <= names
    set_field(browser, "generate-seed", 3)
    browser.find_element(By.ID, "generate").click()
    wait_for(browser, lambda d: text(d, "message").startswith("drew"), what="the world")
    idle(browser)
    drawn = get_map(browser)
    assert drawn["name"] == "floorplan-3" and len(drawn["walls"]) > 4 and drawn["zones"]
    screenshot(browser, tmp_path / "screenshots", "generated", docs=True)
    browser.find_element(By.ID, "undo").click()  # the map before the draw
    assert get_map(browser)["walls"] == [[0, 0, 1, 0]]
    browser.find_element(By.ID, "redo").click()
    assert get_map(browser) == drawn
    set_field(browser, "filename", "drawn.json")
    assert save(browser).startswith("saved")
    saved = json.loads((scratch.root / "drawn.json").read_text())
    assert saved["walls"] == drawn["walls"]
    assert [p for p in check_map(saved) if p.severity == "error"] == []
