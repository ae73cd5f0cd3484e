"""The live web view in a real browser: headless Chromium (selenium) against
`afe serve --http` on loopback with a synthetic source: the page draws the stream and
edits the graph; started without requests it says how to begin and draws what is added,
without a console error; a page of another origin in the same browser is refused.
Skipped, with the reason, where Chromium, chromedriver or selenium is missing;
`.ci/run` installs them so CI never skips."""
import json
import os
import shutil
import socket
import subprocess
import time

import pytest

from conftest import connect, free_port

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
SOURCE = "synth:fs=16000,tone=440,noise=0.1,itd_ms=0.3,ild_db=-6,seed=1"


def _browser():
    chromium = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
    driver = shutil.which("chromedriver")
    try:
        import selenium  # noqa: F401
    except ImportError:
        pytest.skip("selenium is not installed (pip install selenium)")
    if not chromium or not driver:
        pytest.skip("no Chromium/chromedriver here (Debian: apt-get install chromium chromium-driver)")
    return chromium, driver


def _wait_for_port(port, proc, timeout=10.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if proc.poll() is not None:
            raise AssertionError(f"afe serve exited: {proc.stderr.read()}")
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
            return
        except OSError:
            time.sleep(0.05)
    raise AssertionError("afe serve did not listen")


def test_the_live_page_shows_the_stream_and_edits_the_graph(cli):
    chromium, driver_path = _browser()
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select, WebDriverWait

    port = free_port()
    server = subprocess.Popen(
        [cli, "serve", "--source", SOURCE, "-r", "ratemap,ild", "-p", "fb_nChannels=16",
         "--http", f"127.0.0.1:{port}", "--listen", "tcp/127.0.0.1:0", "--for", "30", "--json"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    opts = webdriver.ChromeOptions()
    opts.binary_location = chromium
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1200,1400", "--autoplay-policy=no-user-gesture-required"):
        opts.add_argument(arg)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    browser = None
    try:
        _wait_for_port(port, server)
        browser = webdriver.Chrome(service=Service(driver_path), options=opts)
        browser.get(f"http://127.0.0.1:{port}/")
        wait = WebDriverWait(browser, 10)
        wait.until(lambda b: b.find_element(By.ID, "conn").text == "live")
        wait.until(lambda b: int(b.find_element(By.ID, "frames").text) > 0)
        wait.until(lambda b: b.find_elements(By.ID, "panel-ratemap_left"))
        canvas = "return document.querySelector('#panel-ratemap_left canvas.data').toDataURL()"
        wave = "return document.getElementById('wave').toDataURL()"
        before = (browser.execute_script(canvas), browser.execute_script(wave))
        start = int(browser.find_element(By.ID, "frames").text)
        time.sleep(1.0)
        assert browser.execute_script(canvas) != before[0], "the ratemap canvas does not move"
        assert browser.execute_script(wave) != before[1], "the waveform does not move"

        # a request added from the page gets its panel
        Select(browser.find_element(By.ID, "request")).select_by_visible_text("itd")
        browser.find_element(By.ID, "add").click()
        wait.until(lambda b: b.find_elements(By.ID, "panel-itd_mono"))

        # 10 s more: the counter follows real time, nothing lost
        time.sleep(9.0)
        frames = int(browser.find_element(By.ID, "frames").text)
        assert 0.8 * 10 * 16000 < frames - start < 1.2 * 10 * 16000, (start, frames)
        assert browser.find_element(By.ID, "lost").text == "0"
        stats = browser.execute_script("return window.afeStats")
        assert stats["lost"] == 0 and stats["batches"] > 150, stats

        shots = os.path.join(ROOT, "target", "artifacts")
        os.makedirs(shots, exist_ok=True)
        shot = os.path.join(shots, "live-view.png")
        browser.save_screenshot(shot)
        print(f"\nscreenshot of the live view: {shot}")
        assert os.path.getsize(shot) > 20_000

        errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
        assert errors == [], errors
    finally:
        if browser is not None:
            browser.quit()
        server.terminate()
        out, err = server.communicate(timeout=10)
    report = json.loads(out)
    assert report["lost_frames"] == 0, report


def _seed_robot_at_16k(root, tmp_path):
    """The file of the seed robot's descriptor at the synthetic source's rate."""
    with open(os.path.join(root, "data", "platforms", "ball-15cm.json")) as f:
        platform = json.load(f)
    platform["audio"]["sample_rate_hz"] = 16000.0
    platform_file = tmp_path / "ball-16k.json"
    platform_file.write_text(json.dumps(platform))
    return platform_file


def _chrome(chromium, driver_path):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = chromium
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1200,1000"):
        opts.add_argument(arg)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service(driver_path), options=opts)


def test_a_page_started_without_requests_says_so_and_draws_what_is_added(cli, root, tmp_path):
    chromium, driver_path = _browser()
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select, WebDriverWait

    platform_file = _seed_robot_at_16k(root, tmp_path)
    port = free_port()
    server = subprocess.Popen(
        [cli, "serve", "--source", SOURCE, "-p", "fb_nChannels=16", "--platform", str(platform_file),
         "--http", f"127.0.0.1:{port}", "--listen", "tcp/127.0.0.1:0", "--for", "30", "--json"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    browser = None
    try:
        _wait_for_port(port, server)
        browser = _chrome(chromium, driver_path)
        browser.get(f"http://127.0.0.1:{port}/")
        wait = WebDriverWait(browser, 10)
        wait.until(lambda b: b.find_element(By.ID, "conn").text == "live")
        # the robot, from its platform descriptor
        robot = browser.find_element(By.ID, "robot")
        wait.until(lambda b: robot.is_displayed())
        assert robot.text == ("seed robot: a 15-cm ball on a pan unit · 2 microphones "
                              "(left-ear, right-ear) · head sphere:radius=0.075,ears=90"), robot.text
        assert json.loads(robot.get_attribute("title"))["joints"][0]["name"] == "neck_yaw"
        empty = browser.find_element(By.ID, "empty")
        wait.until(lambda b: empty.is_displayed())
        assert "no request yet" in empty.text
        # the input still scrolls, and a second of it raises no error
        wave = "return document.getElementById('wave').toDataURL()"
        wait.until(lambda b: int(b.find_element(By.ID, "frames").text) > 0)
        before = browser.execute_script(wave)
        time.sleep(1.0)
        assert browser.execute_script(wave) != before, "the waveform does not move"
        assert [e for e in browser.get_log("browser") if e["level"] == "SEVERE"] == []

        Select(browser.find_element(By.ID, "request")).select_by_visible_text("ratemap")
        browser.find_element(By.ID, "add").click()
        wait.until(lambda b: b.find_elements(By.ID, "panel-ratemap_left"))
        assert not empty.is_displayed()
        canvas = "return document.querySelector('#panel-ratemap_left canvas.data').toDataURL()"
        before = browser.execute_script(canvas)
        time.sleep(1.0)
        assert browser.execute_script(canvas) != before, "the ratemap canvas does not move"
        assert "placed ratemap" in browser.find_element(By.ID, "log").text
        assert [e for e in browser.get_log("browser") if e["level"] == "SEVERE"] == []
    finally:
        if browser is not None:
            browser.quit()
        server.terminate()
        server.communicate(timeout=10)


def test_a_page_of_another_origin_in_the_same_browser_is_refused(cli):
    chromium, driver_path = _browser()
    from selenium.webdriver.support.ui import WebDriverWait

    port, other = free_port(), free_port()
    server = subprocess.Popen(
        [cli, "serve", "--source", SOURCE, "-r", "ratemap", "--http", f"127.0.0.1:{port}",
         "--listen", "tcp/127.0.0.1:0", "--for", "20"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    # the other site: any page served from another port of loopback
    site = subprocess.Popen(
        ["/usr/bin/env", "python3", "-m", "http.server", str(other), "--bind", "127.0.0.1"],
        cwd=os.path.dirname(__file__), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    probe = f"""
      window.probe = [];
      const ws = new WebSocket("ws://127.0.0.1:{port}/ws");
      ws.onopen = () => window.probe.push("open");
      ws.onmessage = () => window.probe.push("message");
      ws.onclose = (ev) => window.probe.push("close " + ev.code);
    """
    browser = None
    try:
        _wait_for_port(port, server)
        _wait_for_port(other, site)
        browser = _chrome(chromium, driver_path)
        browser.get(f"http://127.0.0.1:{other}/")
        browser.execute_script(probe)
        wait = WebDriverWait(browser, 10)
        wait.until(lambda b: b.execute_script("return window.probe.length") > 0)
        assert browser.execute_script("return window.probe") == ["close 1006"]
        # the page's own origin is served in the same browser
        browser.get(f"http://127.0.0.1:{port}/")
        wait.until(lambda b: b.execute_script("return window.afeStats.batches") > 0)
    finally:
        if browser is not None:
            browser.quit()
        site.terminate()
        site.wait(timeout=10)
        server.terminate()
        _, err = server.communicate(timeout=10)
    assert f"refused a WebSocket: origin http://127.0.0.1:{other} is not this server's page" in err, err


def test_the_page_shows_the_tracked_sources_from_above_turned_by_the_reported_yaw(cli, root, tmp_path):
    # the seed robot serving `tracking`; a motor controller (afe.connect) reports its head
    # turned 20 deg to the left on afe/<name>/head/yaw, and the page draws the robot from
    # above: the head's yaw, the tracked sources with their spread, the suggested turn
    chromium, driver_path = _browser()
    from selenium.webdriver.support.ui import WebDriverWait

    platform_file = _seed_robot_at_16k(root, tmp_path)
    port, zport = free_port(), free_port()
    server = subprocess.Popen(
        [cli, "serve", "--source", SOURCE, "-r", "tracking", "--platform", str(platform_file),
         "--http", f"127.0.0.1:{port}", "--listen", f"tcp/127.0.0.1:{zport}", "--for", "30", "--json"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    browser = None
    try:
        _wait_for_port(port, server)
        robot = connect(f"tcp/127.0.0.1:{zport}")
        robot.set_head_yaw(0.0, 20.0)
        with pytest.raises(ValueError, match="not finite"):
            robot.set_head_yaw(1.0, float("nan"))
        browser = _chrome(chromium, driver_path)
        browser.get(f"http://127.0.0.1:{port}/")
        wait = WebDriverWait(browser, 15)
        panel = "document.querySelector('#panel-tracking_mono')"
        wait.until(lambda b: b.execute_script(f"return {panel} && +{panel}.dataset.sources > 0"))
        words = browser.execute_script(f"return {panel}.querySelector('canvas.data').title")
        assert words.startswith("head 20°"), words
        assert "#1 " in words or "#2 " in words, words
        assert browser.execute_script(f"return getComputedStyle({panel}.querySelector('.bar')).display") == "none"
        assert [e for e in browser.get_log("browser") if e["level"] == "SEVERE"] == []
        robot.close()
    finally:
        if browser is not None:
            browser.quit()
        server.terminate()
        server.communicate(timeout=10)
