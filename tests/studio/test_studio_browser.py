"""The studio in a real browser (headless Chromium through Selenium): a short run started with
``--studio``, its curves and surfaces drawn, a design favoured and another given a hand fitness
through the page while the run is paused, both recorded at the generation the run went on from, and
the steered run replayed with ``genr8 edit`` and ``genr8 resume`` equal to it row for row.

Screenshots of the start, middle and end go to ``$GENR8_STUDIO_SHOTS`` when set (else the test's
temporary folder)."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

CONFIG = """\
universe = "default"
seed = 11

[genome]
length = 40
max_depth = 5

[ea]
population = 10
generations = {generations}
elites = 1
tournament = 2

[environment]
steps = 3
scale = 1.5

[[environment.attractors]]
position = [0.0, 0.0, 2.5]
constant = 1.5

[islands]
count = 2
migration_interval = 2
migrants = 1
"""


def _rows(run_dir):
    from genr8_dist.store import TIMING_COLUMNS, RunStore

    table = RunStore.open(run_dir).individuals().drop_columns([*TIMING_COLUMNS, "run_id"])
    table = table.sort_by([("island", "ascending"), ("generation", "ascending"), ("index", "ascending")])
    return [{k: ("nan" if isinstance(v, float) and v != v else v) for k, v in r.items()}
            for r in table.to_pylist()]


def _genr8(*args, timeout=300):
    proc = subprocess.run([sys.executable, "-m", "genr8_dist.cli", *args], capture_output=True, text=True,
                          timeout=timeout)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def test_a_run_watched_and_steered_from_the_studio_replays_row_for_row(tmp_path, studio):
    from selenium.webdriver.common.by import By

    from genr8_dist.store import RunStore

    shots = Path(os.environ.get("GENR8_STUDIO_SHOTS") or tmp_path)
    shots.mkdir(parents=True, exist_ok=True)
    last = 40
    config = tmp_path / "run.toml"
    config.write_text(CONFIG.format(generations=last))
    live = tmp_path / "live"
    page = studio("run", str(config), "--run-dir", str(live), "--cpus", "2", "--studio", "--studio-port", "0")
    driver, data, _wait = page.driver, page.data, page.wait
    _wait("curves and a surface", lambda: int(data("curve-points") or 0) >= 1
          and int(data("surfaces") or 0) >= 1, 180)
    time.sleep(1.5)
    assert page.colours(shots / "studio-start.png") > 50

    # pause the run between epochs, then steer it through the page
    driver.find_element(By.ID, "pause").click()
    _wait("the run to pause", lambda: driver.find_element(By.ID, "status").text.lower() == "paused", 120)
    paused_at = RunStore.open(live).committed_generations()
    assert min(paused_at.values()) < last, "the run ended before it could be paused"
    _wait("the paused generation's surfaces", lambda: data("generation") == str(min(paused_at.values()))
          and int(data("surfaces") or 0) >= 1, 60)
    rows = [r for r in driver.find_elements(By.CSS_SELECTOR, "#gen-list [data-id]")
            if "invalid" not in (r.get_attribute("class") or "")]
    favoured, scored = rows[0].get_attribute("data-id"), rows[-1].get_attribute("data-id")
    rows[0].click()
    _wait("the favoured design's panel", lambda: driver.find_element(By.ID, "d-id").text == favoured, 30)
    driver.find_element(By.ID, "favour").click()
    _wait("the favour to be recorded",
          lambda: "v2" in driver.find_element(By.ID, "interventions").text, 60)
    driver.find_element(By.CSS_SELECTOR, f'#gen-list [data-id="{scored}"]').click()
    _wait("the scored design's panel", lambda: driver.find_element(By.ID, "d-id").text == scored, 30)
    field = driver.find_element(By.ID, "hand-value")
    field.clear()
    field.send_keys("0")
    driver.find_element(By.ID, "hand-set").click()
    _wait("the hand fitness to be recorded",
          lambda: "hand fitness" in driver.find_element(By.ID, "interventions").text, 60)
    time.sleep(1.0)
    assert page.colours(shots / "studio-middle.png") > 50

    driver.find_element(By.ID, "pause").click()            # now "Continue"
    _wait("the run to complete", lambda: driver.find_element(By.ID, "status").text.lower() == "complete",
          300)
    _wait("the last generation in view", lambda: data("generation") == str(last)
          and int(data("surfaces") or 0) >= 1, 120)
    time.sleep(1.5)
    assert page.colours(shots / "studio-end.png") > 50
    rc = page.stop(signals=1, patience=60)
    assert rc == 0, "".join(page.lines[-20:])

    # both interventions are recorded, as genr8 edit records them, at the generation after the pause
    store = RunStore.open(live)
    events = store.events().to_pylist()
    kinds = [e["kind"] for e in events]
    assert kinds.count("pause") == 1 and kinds.count("continue") == 1 and kinds[-1] == "complete"
    interventions = [(e["generation"], json.loads(e["detail"]))
                     for e in events if e["kind"] == "intervention"]
    assert len(interventions) == 2
    (g1, favour), (g2, hand) = interventions
    at = min(paused_at.values()) + 1
    assert g1 == g2 == at
    assert favour["source"] == hand["source"] == "studio"
    assert favour["injected"][0]["copy_of"] == favoured and favour["injected"][0]["favoured"]
    assert hand["hand_fitness"][0]["id"] == scored and hand["hand_fitness"][0]["fitness"] == 0.0
    got = _rows(live)
    assert {r["config_version"] for r in got if r["generation"] == at} == {3}
    assert {r["config_version"] for r in got if r["generation"] == at - 1} == {1}
    assert [r["parents"] for r in got if r["origin"] == "injected"] == [[favoured]]
    scored_island = int(scored.split("-")[0])
    assert [scored] in [r["parents"] for r in got if r["generation"] == at and r["island"] == scored_island
                        and r["origin"] == "elite"]

    # replayed: a run stopped at the same generation, edited from the CLI and resumed, equals it
    config_b = tmp_path / "b.toml"
    config_b.write_text(CONFIG.format(generations=at - 1))
    replay = tmp_path / "replay"
    _genr8("run", str(config_b), "--run-dir", str(replay), "--cpus", "2", "--quiet")
    _genr8("edit", str(replay), "--generations", str(last - at + 1), "--favour", favoured)
    _genr8("edit", str(replay), "--hand-fitness", f"{scored}=0")
    _genr8("resume", str(replay), "--cpus", "2", "--quiet")
    assert _rows(replay) == got


def test_the_studio_streams_generations_before_their_commit(tmp_path, studio):
    """A run of one long epoch (nothing committed until its end): the page never says generation -1;
    within its first seconds it shows the founders and then each generation the islands complete,
    drawn in 3D and marked "not yet committed", a design of it selectable; after the commit the same
    generation is shown as durable."""
    from selenium.common.exceptions import StaleElementReferenceException
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    from genr8_dist.store import RunStore

    shots = Path(os.environ.get("GENR8_STUDIO_SHOTS") or tmp_path)
    shots.mkdir(parents=True, exist_ok=True)
    last = 80   # one epoch long enough (about 15 s on an idle 2-core machine) to look at before it commits
    config = tmp_path / "run.toml"
    config.write_text(CONFIG.format(generations=last).replace("migration_interval = 2",
                                                               f"migration_interval = {last}"))
    live = tmp_path / "live"
    started = time.monotonic()
    labels: list[str] = []
    page = studio("run", str(config), "--run-dir", str(live), "--cpus", "2", "--studio", "--studio-port", "0")
    driver, data, _wait, lines = page.driver, page.data, page.wait, page.lines

    def live_generation_drawn():
        labels.append(driver.find_element(By.ID, "gen-label").text)
        return data("durable") == "false" and int(data("surfaces") or 0) >= 1

    _wait("a generation shown before its commit", live_generation_drawn, 180)
    assert RunStore.open(live).committed_generations() == {}, "the epoch committed before the test looked"
    time.sleep(1.0)
    assert page.colours(shots / "studio-first-seconds.png") > 50
    seconds = time.monotonic() - started
    assert "not yet committed" in driver.find_element(By.ID, "gen-view").text
    assert not any("-1" in label for label in labels)
    assert any("founders" in label or "committed none yet" in label for label in labels)
    def click_a_design():   # the list is drawn again as each island's generation arrives: find it again
        try:
            row = next(r for r in driver.find_elements(By.CSS_SELECTOR, "#gen-list [data-id]")
                       if "invalid" not in (r.get_attribute("class") or ""))
            found = row.get_attribute("data-id")
            row.click()
            return found
        except StaleElementReferenceException:
            return None

    ident = _wait("a design of the list clicked", click_a_design, 30)
    _wait("the design's panel", lambda: driver.find_element(By.ID, "d-id").text == ident, 30)
    assert "not yet committed" in driver.find_element(By.ID, "d-origin").text

    # parallel coordinates: a line per valid design; a brush along the fitness axis keeps the
    # designs in its range, in the list and in 3D
    driver.find_element(By.ID, "follow").click()          # hold this generation while brushing
    _wait("every island's part of it", lambda: "2 islands" in driver.find_element(By.ID, "gen-view").text
          or data("durable") == "true", 120)
    time.sleep(1.5)
    lines_drawn = driver.find_elements(By.CSS_SELECTOR, "#pc path.design")
    valid = driver.find_elements(By.CSS_SELECTOR, "#gen-list [data-id]:not(.invalid)")
    assert len(lines_drawn) == len(valid) >= 4
    axis = driver.find_element(By.CSS_SELECTOR, '#pc g[data-axis="fitness"] rect.hit')
    height = axis.size["height"]
    ActionChains(driver).move_to_element_with_offset(axis, 0, int(height * 0.5) - 6).click_and_hold() \
        .move_by_offset(0, -int(height * 0.35)).pause(0.2).release().perform()
    _wait("the brush to apply", lambda: 0 < int(data("brushed") or 0) < len(valid), 20)
    brushed = int(data("brushed"))
    _wait("the brushed designs in 3D", lambda: 1 <= int(data("surfaces") or 0) <= brushed, 60)
    # the list and the dimmed lines follow the brush (a list re-rendered as the generation's last
    # island arrives catches up within a poll)
    _wait("the list to keep only the brushed designs", lambda: len(driver.find_elements(
        By.CSS_SELECTOR, "#gen-list [data-id]:not(.invalid)")) == int(data("brushed")), 20)
    brushed = int(data("brushed"))
    assert 0 < brushed < len(valid)
    assert len(driver.find_elements(By.CSS_SELECTOR, "#pc path.design.out")) == len(valid) - brushed
    time.sleep(1.0)
    driver.save_screenshot(str(shots / "studio-parallel-coordinates.png"))
    driver.find_element(By.ID, "pc-clear").click()
    _wait("the brush cleared", lambda: int(data("brushed") or 0) == len(valid), 20)
    driver.find_element(By.ID, "follow").click()
    shown = [int(data("generation"))]
    _wait("a later generation, still before the commit", lambda: shown.append(int(data("generation")))
          or shown[-1] > shown[0] or RunStore.open(live).committed_generations(), 240)
    _wait("the run to complete", lambda: driver.find_element(By.ID, "status").text.lower() == "complete",
          600)
    _wait("the last generation, durable", lambda: data("generation") == str(last)
          and data("durable") == "true", 60)
    _wait("the studio to stay open", lambda: any("the studio stays open" in ln for ln in lines), 60)
    rc = page.stop()
    assert rc == 0, "".join(lines[-20:])
    assert not (live / "live").exists() and not (live / "_running.lock").exists()
    print(f"first live generation drawn {seconds:.0f} s after `genr8 run` started; generations seen "
          f"before the commit: {sorted(set(shown))}")


def _stored_run(path: Path, search: dict | None) -> None:
    """A small finished run of one island, made without Ray (the island's generations committed)."""
    from genr8_dist.config import RunConfig
    from genr8_dist.evolution import Island
    from genr8_dist.store import RunStore

    fitness = {"undulation": {"target": 1.5, "weight": 1.0}, "subdivisions": {"target": 0.5, "weight": 1.0},
               "symmetry": {"target": 1.0, "weight": 2.0}, "slivers": {"target": 0.0, "weight": 1.0}}
    base = {"universe": "tiles", "seed": 3, "genome": {"length": 60}, "fitness": fitness,
            "ea": {"population": 16, "generations": 3}, "environment": {"steps": 2}}
    config = RunConfig.from_dict({**base, "search": search} if search else base)
    store = RunStore.create(path, config.to_toml())
    for generation in Island(config, 0).run():
        store.commit(generation)


def _front(view, names):
    """The ids of the newest generation's valid designs no other dominates in ``names`` (each the
    weighted distance to its target, as the page computes it), and every plotted id."""
    crits = {c["name"]: c for c in view.state()["criteria"]}
    points = {}
    for r in view.generation()["individuals"]:
        values = [r["criteria"].get(n) for n in names]
        if r["valid"] and all(v is not None for v in values):
            points[r["id"]] = [crits[n]["weight"] * abs(v - crits[n]["target"]) / crits[n]["unit"]
                               for n, v in zip(names, values, strict=True)]
    front = {i for i, p in points.items() if not any(
        j != i and all(a <= b for a, b in zip(q, p, strict=True)) and q != p for j, q in points.items())}
    return front, points


@pytest.mark.parametrize("search", [
    {"mode": "pareto", "objectives": ["undulation", "subdivisions", "symmetry", "slivers"]}, None])
def test_objective_space_kinds_statistics_and_a_layout_without_overlap(tmp_path, studio, search):
    """A stored run (pareto, then weighted) in the studio: the parallel coordinates sit below the 3D
    view, not over it; the objective space shows every valid design of the generation with the
    non-dominated ones of the chosen objectives highlighted (3D, then 2D), and a click on a point
    selects that design and shows its surface; the kinds of form list each cluster's ranges."""
    from selenium.webdriver.common.actions.action_builder import ActionBuilder
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select

    from genr8_dist.studio.data import RunView

    shots = Path(os.environ.get("GENR8_STUDIO_SHOTS") or tmp_path)
    shots.mkdir(parents=True, exist_ok=True)
    name = "pareto" if search else "weighted"
    run = tmp_path / name
    _stored_run(run, search)
    view = RunView(str(run))
    page = studio("studio", str(run), "--port", "0", timeout=60)
    driver, data, _wait = page.driver, page.data, page.wait

    def rect(css):
        return driver.execute_script(f"const r = document.querySelector('{css}').getBoundingClientRect();"
                                     "return [r.left, r.top, r.right, r.bottom];")

    _wait("the surfaces", lambda: int(data("surfaces") or 0) >= 4, 120)
    assert rect("#pc-panel")[1] >= rect("#viewport")[3] - 1      # below the 3D view, not over it

    driver.find_element(By.ID, "show-objectives").click()
    names = [Select(driver.find_element(By.ID, f"obj-{a}")).first_selected_option.get_attribute("value")
             for a in "xyz"]
    if search:
        assert names == search["objectives"][:3]                  # the run's objectives first
    front, plotted = _front(view, names)
    _wait("the points", lambda: int(data("objective-points") or 0) == len(plotted), 30)
    assert set(data("objective-front-ids").split()) == front and 1 <= len(front) < len(plotted)
    assert rect("#objective")[0] >= rect("#viewport")[2] - 1      # beside the surfaces
    time.sleep(1.5)
    assert page.colours(shots / f"studio-objectives-3d-{name}.png") > 50

    Select(driver.find_element(By.ID, "obj-z")).select_by_value("")      # 2 objectives
    front2, _ = _front(view, names[:2])
    _wait("the 2D front", lambda: set((data("objective-front-ids") or "").split()) == front2, 20)
    time.sleep(1.0)
    driver.save_screenshot(str(shots / f"studio-objectives-2d-{name}.png"))

    # a click on a point with no other within a sphere's width (copies, and designs whose values
    # differ by rounding, are drawn on one spot), not among the surfaces shown where one is: selected,
    # and its surface shown
    shown = set(driver.execute_script("return window.studio.order"))
    _, flat = _front(view, names[:2])
    at = {i: driver.execute_script("return window.studio.objectiveAt(arguments[0])", i) for i in flat}

    def room(i: str) -> float:   # pixels to the nearest other point
        return min((math.dist(at[i], at[j]) for j in flat if j != i), default=1e9)

    clear = [i for i in sorted(flat) if room(i) >= 12]
    assert clear, f"every point of the 2D objective space has another within 12 px: {at}"
    ident = max(clear, key=lambda i: (i not in shown, i))
    x, y = at[ident]
    click = ActionBuilder(driver)
    click.pointer_action.move_to_location(int(x), int(y)).click()
    click.perform()
    _wait("the clicked design's panel", lambda: driver.find_element(By.ID, "d-id").text == ident, 30)
    _wait("its surface", lambda: ident in driver.execute_script("return window.studio.order")
          and driver.execute_script("return window.studio.designs.has(arguments[0])", ident), 60)

    # the kinds of form, each with its size and its criteria's ranges over its members
    Select(driver.find_element(By.ID, "count")).select_by_value("kinds")
    _wait("the kinds", lambda: int(data("kinds") or 0) >= 2, 120)
    kinds = view.clusters(None, 12)["representatives"]
    texts = [e.text for e in driver.find_elements(By.CSS_SELECTOR, "#kinds-list .ranges")]
    assert len(texts) == len(kinds)
    weighted = {c["name"] for c in view.state()["criteria"] if c["weight"]}
    for text, kind in zip(texts, kinds, strict=True):
        assert set(kind["ranges"]) == {"fitness", *weighted}
        assert text.startswith("fitness ") and "symmetry " in text
        low, high = kind["ranges"]["symmetry"]
        if all(v == 0 or 1e-4 <= abs(v) < 1000 for v in (low, high)):   # no exponent either side
            shown = f"{low:.3g}" if f"{low:.3g}" == f"{high:.3g}" else f"{low:.3g}–{high:.3g}"
            assert f"symmetry {shown}" in text, text
    page.stop(signal.SIGINT, signals=1)
