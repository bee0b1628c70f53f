"""The studio's server without Ray or a browser: what its API answers over a small run, the actions it
records, and its security rule (loopback host, token, JSON-only actions, files only from its package)."""

from __future__ import annotations

import json
import urllib.error
import urllib.request

import pyarrow.compute as pc
import pytest

from genr8_dist.distributed.coordinator import parse_config
from genr8_dist.evolution.island import Island
from genr8_dist.store import RunStore
from genr8_dist.studio import Studio, is_loopback

TOML = """\
universe = "default"
seed = 3

[genome]
length = 30
max_depth = 4

[ea]
population = 6
generations = 4
elites = 1

[environment]
steps = 2

[[environment.attractors]]
position = [0.0, 0.0, 3.0]
constant = 1.0

[islands]
count = 2
migration_interval = 2
migrants = 1
"""


@pytest.fixture
def run_dir(tmp_path):
    """Generations 0 and 1 of a 2-island run, made by the islands themselves (no Ray)."""
    path = tmp_path / "run"
    store = RunStore.create(path, TOML)
    store.record_event("start", generation=0)
    config = parse_config(TOML, "t")
    islands = [Island(config, i) for i in range(2)]
    first = [isl.initial() for isl in islands]
    store.commit([ind for pop in first for ind in pop])
    store.commit([ind for isl, pop in zip(islands, first, strict=True) for ind in isl.step(pop, 1)])
    return path


@pytest.fixture
def studio(run_dir):
    s = Studio(str(run_dir), port=0).start()
    yield s
    s.close()


def get(studio, path, headers=None):
    req = urllib.request.Request(f"http://127.0.0.1:{studio.port}{path}", headers=headers or {})
    with urllib.request.urlopen(req, timeout=30) as r:
        return r.status, r.headers.get("Content-Type"), r.read()


def post(studio, body, headers=None, host="127.0.0.1"):
    data = json.dumps(body).encode()
    h = {"Content-Type": "application/json", "X-Genr8-Studio": "1"} if headers is None else headers
    req = urllib.request.Request(f"http://{host}:{studio.port}/api/act", data=data, headers=h, method="POST")
    try:
        with urllib.request.urlopen(req, timeout=60) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as exc:
        return exc.code, json.loads(exc.read())


def test_state_curves_generation_and_a_design(studio):
    status, kind, body = get(studio, "/api/state")
    state = json.loads(body)
    assert status == 200 and kind == "application/json"
    assert (state["status"], state["generation"], state["last_generation"]) == ("stopped", 1, 4)
    # stopped with no trace of how (no interrupt event): no rate and no time left are made up
    assert (state["individuals_per_second"], state["seconds_left"]) == (None, None)
    assert [i["generation"] for i in state["islands"]] == [1, 1]
    assert [c["name"] for c in state["criteria"]][:2] == ["size", "smoothness"]
    curves = json.loads(get(studio, "/api/curves")[2])
    assert curves["generation"] == [0, 1] and len(curves["best"]) == 2
    assert set(curves["islands"]) == {"0", "1"} and len(curves["criteria"]["size"]) == 2
    gen = json.loads(get(studio, "/api/generation")[2])
    assert gen["generation"] == 1 and len(gen["individuals"]) == 12
    fitness = [r["fitness"] for r in gen["individuals"] if r["fitness"] is not None]
    assert fitness == sorted(fitness)
    best = gen["individuals"][0]["id"]
    design = json.loads(get(studio, f"/api/individual?id={best}")[2])
    assert design["id"] == best and design["text"] and design["lineage"][0]["id"] == best
    env = json.loads(get(studio, "/api/environment")[2])
    assert env["attractors"] == [{"position": [0.0, 0.0, 3.0], "constant": 1.0}]


def test_the_kinds_of_form_are_one_existing_design_per_cluster(studio, run_dir, monkeypatch):
    from genr8_dist.history._tables import form_ids

    store = RunStore.open(str(run_dir))
    table = store.dataset().to_table()
    table = table.filter(pc.and_(pc.equal(table["generation"], 1), pc.equal(table["valid"], True)))
    forms = form_ids(table)   # mirror images and copies are one form, as the kinds count them
    valid = {i: int(f) for i, f in zip(table["id"].to_pylist(), forms, strict=True)}
    distinct = len(set(valid.values()))
    assert distinct >= 4
    for k, expected in ((4, 4), (12, min(12, distinct))):
        kinds = json.loads(get(studio, f"/api/clusters?g=1&k={k}")[2])
        reps = kinds["representatives"]
        assert (kinds["generation"], kinds["k"], len(reps)) == (1, k, expected)
        assert all(r["id"] in valid for r in reps)                       # existing, valid, of generation 1
        assert len({valid[r["id"]] for r in reps}) == expected           # one surface per cluster
        assert [r["cluster"] for r in reps] == list(range(1, expected + 1))
        assert sum(r["members"] for r in reps) == kinds["surfaces"] == distinct
        assert [r["members"] for r in reps] == sorted((r["members"] for r in reps), reverse=True)
    island = json.loads(get(studio, "/api/clusters?g=1&k=3&island=1")[2])["representatives"]
    assert len(island) == 3 and all(r["id"].startswith("1-1-") for r in island)
    with pytest.raises(urllib.error.HTTPError) as bad:
        get(studio, "/api/clusters?g=1&k=0")
    assert bad.value.code == 400 and "1 to 36 kinds" in json.loads(bad.value.read())["error"]
    monkeypatch.setitem(__import__("sys").modules, "sklearn", None)      # no clustering library needed
    kinds = json.loads(get(studio, "/api/clusters?g=0&k=4")[2])
    assert len(kinds["representatives"]) == 4 and "unavailable" not in kinds


def test_a_surface_is_glb_and_downloads_are_whole_files(studio):
    gen = json.loads(get(studio, "/api/generation")[2])
    best = next(r["id"] for r in gen["individuals"] if r["valid"])
    status, kind, glb = get(studio, f"/api/surface?id={best}")
    assert status == 200 and kind == "model/gltf-binary" and glb[:4] == b"glTF"
    import io

    import trimesh

    scene = trimesh.load(io.BytesIO(glb), file_type="glb")
    assert any(getattr(g, "faces", None) is not None and len(g.faces) for g in scene.geometry.values())
    _, _, obj = get(studio, f"/api/download?id={best}&format=obj")
    assert obj.lstrip().startswith(b"#") and b"\nv " in obj and b"\nf " in obj
    _, _, rhino = get(studio, f"/api/download?id={best}&format=3dm")
    import rhino3dm

    model = rhino3dm.File3dm.FromByteArray(rhino)
    assert len(model.Objects) >= 1


def test_a_large_surface_is_decimated():
    import numpy as np
    import trimesh

    from genr8_dist.studio.data import MAX_FACES, _decimate

    grid = trimesh.creation.box().subdivide().subdivide().subdivide().subdivide().subdivide().subdivide()
    assert len(grid.faces) > MAX_FACES
    small = _decimate(grid, MAX_FACES)
    assert 0 < len(small.faces) <= MAX_FACES
    assert np.allclose(small.bounds, grid.bounds, atol=0.2)


def test_favour_and_hand_fitness_of_a_stopped_run_are_recorded_as_edit_records_them(studio, run_dir):
    status, answer = post(studio, {"action": "favour", "ids": ["0-1-2"]})
    assert status == 200 and answer["queued"] is None and answer["effective_generation"] == 2
    status, answer = post(studio, {"action": "hand_fitness", "id": "1-1-0", "fitness": 0.0})
    assert status == 200 and answer["version"] == 3
    events = [e for e in RunStore.open(run_dir).events().to_pylist() if e["kind"] == "intervention"]
    details = [json.loads(e["detail"]) for e in events]
    assert [e["generation"] for e in events] == [2, 2]
    assert details[0]["injected"][0]["copy_of"] == "0-1-2" and details[0]["source"] == "studio"
    assert details[1]["hand_fitness"][0]["id"] == "1-1-0"
    state = json.loads(get(studio, "/api/state")[2])
    assert [e["label"] for e in state["interventions"]] == ["v2", "v3"]


def test_bad_actions_are_one_line_errors_that_change_nothing(studio, run_dir):
    before = sorted(p.name for p in (run_dir / "_manifest").iterdir())
    for body, words in [({"action": "favour", "ids": ["../etc"]}, "ISLAND-GENERATION-INDEX"),
                        ({"action": "favour", "ids": ["0-9-0"]}, "0-9-0"),
                        ({"action": "hand_fitness", "id": "0-1-0", "fitness": "x"}, "fitness"),
                        ({"action": "set", "assignments": ["fitness.beauty.weight=1"]}, "beauty"),
                        ({"action": "pause"}, "not running"),
                        ({"action": "rm -rf"}, "unknown action")]:
        status, answer = post(studio, body)
        assert status == 400 and words in answer["error"], (body, answer)
    assert sorted(p.name for p in (run_dir / "_manifest").iterdir()) == before


def test_security_rule(studio, run_dir):
    # actions must be JSON with the studio's header (a cross-site form cannot send it)
    status, _ = post(studio, {"action": "favour", "ids": ["0-1-2"]}, headers={"Content-Type": "text/plain"})
    assert status == 403
    # a Host that is not loopback is refused on the loopback address (DNS rebinding)
    with pytest.raises(urllib.error.HTTPError) as info:
        get(studio, "/api/state", headers={"Host": "evil.example:80"})
    assert info.value.code == 403
    # only the package's own files are served
    for path in ["/static/../server.py", "/static/%2e%2e/server.py", "/static/vendor/three/LICENSE",
                 "/etc/passwd", f"/static/{run_dir}/_manifest"]:
        with pytest.raises(urllib.error.HTTPError) as info:
            get(studio, path)
        assert info.value.code == 404, path
    assert get(studio, "/static/vendor/three/three.module.min.js")[0] == 200
    assert is_loopback("127.0.0.1") and is_loopback("::1") and not is_loopback("0.0.0.0")


def test_bound_elsewhere_a_token_is_required(run_dir):
    s = Studio(str(run_dir), host="0.0.0.0", port=0).start()
    try:
        assert s.token and f"?token={s.token}" in s.url
        with pytest.raises(urllib.error.HTTPError) as info:
            get(s, "/api/state")
        assert info.value.code == 403
        with pytest.raises(urllib.error.HTTPError):
            get(s, "/api/state?token=wrong")
        assert get(s, f"/api/state?token={s.token}")[0] == 200
        status, _, _ = get(s, "/api/state", headers={"Cookie": f"genr8_studio_token={s.token}"})
        assert status == 200
        req = urllib.request.Request(f"http://127.0.0.1:{s.port}/?token={s.token}")
        with urllib.request.urlopen(req, timeout=30) as r:
            cookie = r.headers.get("Set-Cookie")
            assert "HttpOnly" in cookie and "SameSite=Strict" in cookie
    finally:
        s.close()


def test_genr8_studio_refuses_what_is_not_a_run(tmp_path, capsys):
    from genr8_dist.cli import main

    assert main(["studio", str(tmp_path / "nowhere")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("genr8: error:") and "nowhere" in err and len(err.strip().splitlines()) == 1


def test_the_pareto_front_is_the_non_dominated_valid_designs(run_dir):
    """Each generation's designs are marked on or off the Pareto front of the weighted criteria's
    deviations from their targets; checked against a plain pairwise comparison."""
    from genr8_dist.studio import RunView

    view = RunView(str(run_dir))
    gen = view.generation(1)
    store = RunStore.open(run_dir)
    spec = store.fitness(store.configs()[0])
    weighted = [c for c in spec.criteria if c.weight]
    rows = {ind.id: ind for i in range(2) for ind in store.load_generation(i, 1)}

    def point(ident):
        return [abs(rows[ident].criteria[c.name] - c.target) / c.unit for c in weighted]

    valid = [r["id"] for r in gen["individuals"] if r["valid"]]
    points = {i: point(i) for i in valid}

    def dominated(i):
        return any(all(a <= b for a, b in zip(points[j], points[i], strict=True)) and points[j] != points[i]
                   for j in valid)

    marked = {r["id"] for r in gen["individuals"] if r["pareto"]}
    assert marked and marked == {i for i in valid if not dominated(i)}


def test_a_rewrite_system_written_in_the_studio_is_injected_and_weights_change(studio, run_dir):
    store = RunStore.open(run_dir)
    text = next(ind.text for ind in store.load_generation(0, 1) if ind.valid)
    status, answer = post(studio, {"action": "inject", "text": text, "island": 1})
    assert status == 200, answer
    status, answer = post(studio, {"action": "set", "assignments": ["fitness.size.weight=3",
                                                                    "environment.gravity=[0, 0, -0.2]"]})
    assert status == 200, answer
    events = [json.loads(e["detail"]) for e in RunStore.open(run_dir).events().to_pylist()
              if e["kind"] == "intervention"]
    (item,) = events[0]["injected"]
    assert item["island"] == 1 and item["source"] == "rewrite system written in the studio"
    assert events[1]["changes"] == {"fitness.size.weight": 3, "environment.gravity": [0, 0, -0.2]}
    config = RunStore.open(run_dir).configs()[-1]
    assert "weight = 3" in config.toml


def test_the_map_elites_archive_of_a_generation(tmp_path):
    """A run searching in map-elites mode: the studio's archive holds, per occupied cell, the valid
    design of lowest fitness over all islands; a weighted run has none."""
    toml = TOML + ('\n[search]\nmode = "map-elites"\ndescriptors = ["n_regions", "size"]\n'
                   "ranges = [[1.0, 30.0], [0.0, 12.0]]\nbins = [3, 4]\n")
    path = tmp_path / "run"
    store = RunStore.create(path, toml)
    config = parse_config(toml, "t")
    population = [ind for i in range(2) for ind in Island(config, i).initial()]
    store.commit(population)
    studio = Studio(str(path), port=0).start()
    try:
        archive = json.loads(get(studio, "/api/archive")[2])
    finally:
        studio.close()
    assert archive["bins"] == [3, 4] and archive["descriptors"] == ["n_regions", "size"]
    expected: dict[tuple[int, int], tuple[float, str]] = {}
    for ind in population:
        if not ind.valid:
            continue
        i = min(2, max(0, int((ind.sizes["regions"] - 1.0) / 29.0 * 3)))
        j = min(3, max(0, int(ind.criteria["size"] / 12.0 * 4)))
        held = expected.get((i, j))
        if held is None or ind.fitness < held[0]:
            expected[(i, j)] = (ind.fitness, ind.id)
    assert {tuple(c["bins"]): c["id"] for c in archive["cells"]} == {k: v[1] for k, v in expected.items()}


def test_a_weighted_run_has_no_archive(studio):
    assert json.loads(get(studio, "/api/archive")[2]) is None


def test_an_action_on_a_finished_run_says_to_add_generations_first(tmp_path):
    toml = TOML.replace("generations = 4", "generations = 0")
    path = tmp_path / "run"
    store = RunStore.create(path, toml)
    config = parse_config(toml, "t")
    store.commit([ind for i in range(2) for ind in Island(config, i).initial()])
    studio = Studio(str(path), port=0).start()
    try:
        status, answer = post(studio, {"action": "favour", "ids": ["0-0-1"]})
        assert status == 400 and "add generations first" in answer["error"]
        status, answer = post(studio, {"action": "generations", "generations": 3})
        assert status == 200 and answer["effective_generation"] == 1
        status, answer = post(studio, {"action": "favour", "ids": ["0-0-1"]})
        assert status == 200 and answer["version"] == 3
    finally:
        studio.close()


def test_the_downloads_listed_are_the_export_tables_and_each_downloads(studio):
    from genr8_dist.export import SURFACE_FORMATS

    best = json.loads(get(studio, "/api/generation")[2])["individuals"][0]["id"]
    listed = json.loads(get(studio, f"/api/individual?id={best}")[2])["downloads"]
    assert listed == [{"format": f.suffix, "label": f.label} for f in SURFACE_FORMATS.values() if f.download]
    assert [d["format"] for d in listed] == ["obj", "glb", "3dm"]
    status, kind, _ = get(studio, f"/api/download?id={best}&format=glb")
    assert (status, kind) == (200, "model/gltf-binary")
    with pytest.raises(urllib.error.HTTPError):
        get(studio, f"/api/download?id={best}&format=stl")      # in the table, not offered
