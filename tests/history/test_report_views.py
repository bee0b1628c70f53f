"""The report's views of issue 29: each kind of form's size and criterion ranges, and the parallel
coordinates of the run's distinct designs, brushed in a real headless Chromium (the page is one file:
its script and data inline, nothing fetched)."""

from __future__ import annotations

import json
import re
import shutil

import pytest
from history_runs import build_real_run

from genr8_dist import history
from genr8_dist.history._search import cluster_ranges, clusters, format_range, weighted_criteria

CHROMIUM = shutil.which("chromium")
DRIVER = shutil.which("chromedriver")


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    path = tmp_path_factory.mktemp("report-views") / "run"
    build_real_run(path)
    page = history.report.write_report(path, path.parent / "r.html", k=5, gallery_k=6)
    return path, page


def test_the_report_lists_each_kind_of_forms_size_and_ranges(report):
    run, page = report
    text = page.read_text(encoding="utf-8")
    section = text[text.index("<h2>Statistics of the kinds of form</h2>"):]
    section = section[:section.index("</section>")]
    for stats in cluster_ranges(clusters(run, 12), weighted_criteria(run)):
        row = re.search(rf'<tr><td class="num">{stats["cluster"]}</td><td class="num">{stats["members"]}</td>'
                        rf"<td><code>{stats['id']}</code></td>(.*?)</tr>", section)
        assert row is not None, stats
        cells = re.findall(r'<td class="num">(.*?)</td>', row.group(1))
        assert cells == [format_range(*stats["ranges"][n]) for n in stats["ranges"]]


def test_the_parallel_coordinates_carry_every_distinct_design_inline(report):
    run, page = report
    text = page.read_text(encoding="utf-8")
    assert not re.search(r"<script[^>]*\bsrc=", text) and "fetch(" not in text
    data = json.loads(re.search(r'<script type="application/json" id="pc-data">(.*?)</script>', text,
                                re.S).group(1))
    distinct = history.top(run, 10_000, distinct=True)
    assert len(data["rows"]) == distinct.num_rows
    assert {r["id"] for r in data["rows"]} == set(distinct["id"].to_pylist())
    assert [a["key"] for a in data["axes"]] == weighted_criteria(run)
    assert [r["fitness"] for r in data["rows"]] == sorted(r["fitness"] for r in data["rows"])


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None or DRIVER is None, reason="chromium and chromedriver are not installed")
def test_brushing_the_reports_parallel_coordinates_selects_designs(report, tmp_path):
    pytest.importorskip("selenium")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    _, page = report
    data = json.loads(re.search(r'id="pc-data">(.*?)</script>', page.read_text(encoding="utf-8"),
                                re.S).group(1))
    options = webdriver.ChromeOptions()
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1400,1000",
                "--disable-background-networking"):
        options.add_argument(arg)
    options.binary_location = CHROMIUM
    driver = webdriver.Chrome(service=Service(DRIVER), options=options)
    try:
        driver.get(page.resolve().as_uri())
        svg = driver.find_element(By.ID, "pc")
        driver.execute_script("arguments[0].scrollIntoView({block: 'center'})", svg)
        lines = driver.find_elements(By.CSS_SELECTOR, "#pc path.design")
        assert len(lines) == len(data["rows"]) >= 4
        body = driver.find_element(By.TAG_NAME, "body")
        assert body.get_attribute("data-brushed") == str(len(data["rows"]))
        axis = driver.find_element(By.CSS_SELECTOR, '#pc g[data-axis="fitness"] rect.hit')
        height = axis.size["height"]
        # brush from below the fitness axis's low end upwards: the better designs
        ActionChains(driver).move_to_element_with_offset(axis, 0, height // 2 - 1).click_and_hold() \
            .move_by_offset(0, -int(height * 0.45)).pause(0.2).release().perform()
        brushed = int(body.get_attribute("data-brushed"))
        assert 0 < brushed < len(data["rows"])
        dimmed = driver.find_elements(By.CSS_SELECTOR, "#pc path.design.out")
        assert len(dimmed) == len(data["rows"]) - brushed
        listed = [r.get_attribute("data-id")
                  for r in driver.find_elements(By.CSS_SELECTOR, "#pc-list tr[data-id]")]
        order = [r["id"] for r in data["rows"]]
        assert listed == sorted(listed, key=order.index) and len(listed) == min(brushed, 50)   # best first
        out = {e.get_attribute("data-id") for e in dimmed}
        fitness = {r["id"]: r["fitness"] for r in data["rows"]}
        assert max(fitness[i] for i in listed) <= min(fitness[i] for i in out)
        driver.save_screenshot(str(tmp_path / "report-parallel.png"))
        line = driver.find_element(By.CSS_SELECTOR, f'#pc path.design[data-id="{listed[0]}"]')
        driver.execute_script("arguments[0].dispatchEvent(new MouseEvent('click', {bubbles: true}))", line)
        picked = driver.find_element(By.CSS_SELECTOR, "#pc-list tr.picked")
        assert picked.get_attribute("data-id") == listed[0]
        assert driver.find_elements(By.CSS_SELECTOR, "#pc path.design.selected")
        driver.find_element(By.ID, "pc-clear").click()
        assert body.get_attribute("data-brushed") == str(len(data["rows"]))
    finally:
        driver.quit()
