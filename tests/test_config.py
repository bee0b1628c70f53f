"""The run configuration: defaults, round trips through TOML, interventions, and refusals that name the
file and the field."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest

from genr8_dist.config import EASettings, GenomeSettings, IslandSettings, RunConfig, load_config
from genr8_dist.errors import ConfigError
from genr8_dist.fitness import FitnessSpec

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def write(tmp_path: Path, text: str, name: str = "run.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_defaults():
    config = RunConfig()
    assert config.universe == "default" and config.seed == 0
    assert config.genome == GenomeSettings() and config.ea == EASettings()
    assert config.islands == IslandSettings() and config.fitness == FitnessSpec()
    assert config.environment.steps == 4


def test_an_empty_file_is_the_default_configuration(tmp_path):
    assert load_config(write(tmp_path, "")) == RunConfig()


def test_full_file(tmp_path):
    path = write(tmp_path, """
universe = "default"
seed = 7
[genome]
length = 40
codon_max = 99
[ea]
population = 12
tournament = 2
mutation_rate = 0.1
[fitness.subdivisions]
target = 0.4
weight = 3
[environment]
steps = 3
gravity = [0.0, 0.0, -0.2]
[islands]
count = 3
topology = "full"
""")
    config = load_config(path)
    assert config.seed == 7 and config.genome.length == 40 and config.genome.codon_max == 99
    assert config.genome.max_depth == GenomeSettings().max_depth
    assert config.ea.population == 12 and config.ea.mutation_rate == 0.1
    assert config.fitness.subdivisions.target == 0.4 and config.fitness.subdivisions.weight == 3.0
    assert config.fitness.size == FitnessSpec().size
    assert config.environment.steps == 3 and tuple(config.environment.gravity) == (0.0, 0.0, -0.2)
    assert config.islands.count == 3 and config.islands.topology == "full"


def test_toml_round_trip(tmp_path):
    config = load_config(write(tmp_path, '[ea]\npopulation = 9\n[environment]\nsteps = 2\nscale = 1.2\n'))
    text = config.to_toml()
    assert tomllib.loads(text) == config.to_dict()
    again = load_config(write(tmp_path, text, "again.toml"))
    assert again == config
    assert again.to_toml() == text


def test_environment_by_path_is_resolved_next_to_the_config(tmp_path):
    (tmp_path / "envs").mkdir()
    write(tmp_path / "envs", "steps = 2\ngravity = [0.0, 0.0, -1.0]\n", "sag.toml")
    path = write(tmp_path, 'environment = "envs/sag.toml"\n')
    config = load_config(path)
    assert config.environment.steps == 2
    # the stored configuration carries the environment inline: it does not depend on the file any more
    assert config.to_dict()["environment"]["steps"] == 2


def test_replace_is_an_intervention():
    config = RunConfig()
    changed = config.replace(ea={"mutation_rate": 0.2}, fitness={"size": {"weight": 4}},
                             environment={"steps": 2}, seed=5)
    assert changed.ea.mutation_rate == 0.2 and changed.ea.population == config.ea.population
    assert changed.fitness.size.weight == 4.0 and changed.fitness.size.target == config.fitness.size.target
    assert changed.environment.steps == 2 and changed.seed == 5
    assert config.ea.mutation_rate == EASettings().mutation_rate  # the original is untouched
    with pytest.raises(ConfigError, match=r"'ea\.mutation_rate'"):
        config.replace(ea={"mutation_rate": -0.5})
    with pytest.raises(ConfigError, match="'population'"):
        config.replace(population=3)


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ("populaton = 3\n", "'populaton'"),
        ("[ea]\npopulaton = 3\n", "'ea.populaton'"),
        ("[ea]\npopulation = \"many\"\n", "'ea.population'"),
        ("[ea]\npopulation = 30.0\n", "'ea.population'"),
        ("[ea]\nmutation_rate = -0.1\n", "'ea.mutation_rate'"),
        ("[ea]\ncrossover_rate = 1.5\n", "'ea.crossover_rate'"),
        ("[ea]\npopulation = 10\ntournament = 11\n", "'ea.tournament'"),
        ("[ea]\nelites = -1\n", "'ea.elites'"),
        ("[genome]\nlength = 0\n", "'genome.length'"),
        ("[genome]\nmax_wraps = true\n", "'genome.max_wraps'"),
        ("universe = \"no-such-universe\"\n", "'universe'"),
        ("seed = -1\n", "'seed'"),
        ("[islands]\ntopology = \"star\"\n", "'islands.topology'"),
        ("[islands]\nmigrants = 30\n", "'islands.migrants'"),
        ("[fitness.size]\nweight = -2\n", "'fitness.size.weight'"),
        ("[fitness.sise]\nweight = 2\n", "'fitness.sise'"),
        ("[environment]\nstepz = 3\n", "stepz"),
        ("environment = \"missing.toml\"\n", "'environment'"),
        ("ea = 3\n", "'ea'"),
    ],
)
def test_bad_configurations_are_refused_naming_file_and_field(tmp_path, text, field):
    path = write(tmp_path, text)
    with pytest.raises(ConfigError) as info:
        load_config(path)
    message = str(info.value)
    assert message.startswith(str(path)), message
    assert field in message, message
    assert "\n" not in message


def test_not_toml_and_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(write(tmp_path, "[ea\n"))
    with pytest.raises(ConfigError, match="not found"):
        load_config(tmp_path / "nope.toml")


def test_sections_validate_when_built_directly():
    with pytest.raises(ConfigError, match=r"'ea\.mutation_rate'"):
        EASettings(mutation_rate=2)
    with pytest.raises(ConfigError, match=r"'islands\.count'"):
        IslandSettings(count=0)


@pytest.mark.parametrize("path", sorted(EXAMPLES.glob("*.toml")), ids=lambda p: p.name)
def test_examples_load(path):
    config = load_config(path)
    assert config.islands.count >= 1
    assert load_config(path).to_toml() == config.to_toml()


def test_a_configuration_survives_pickling_for_ray_actors():
    import pickle

    config = load_config(EXAMPLES / "long.toml")
    again = pickle.loads(pickle.dumps(config))
    assert again == config and again.to_toml() == config.to_toml()


def test_a_stored_configuration_needs_neither_its_mesh_nor_its_universe_files(tmp_path, monkeypatch):
    """Paths in a run TOML are resolved against its folder; what they name is stored in the run."""
    import shutil

    import trimesh

    from genr8_dist.hemls import grow, parse

    folder = tmp_path / "project"
    (folder / "meshes").mkdir(parents=True)
    trimesh.creation.icosphere(subdivisions=1, radius=3.0).export(folder / "meshes" / "ball.obj")
    plugin = folder / "plugins" / "mine"
    plugin.mkdir(parents=True)
    (plugin / "mine.lark").write_text((Path(__file__).parents[1] / "grammars" / "default.lark").read_text())
    toml = folder / "run.toml"
    toml.write_text('universe = "plugins/mine"\n[environment]\nsteps = 2\nstart_position = [0, 0, 0]\n'
                    '[[environment.boundaries]]\nkind = "mesh"\npath = "meshes/ball.obj"\n')
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)          # the paths are the TOML folder's, not the working directory's
    config = load_config(toml)
    stored = config.to_toml()
    shutil.rmtree(folder)
    again = RunConfig.from_toml(stored, source="stored")
    assert again == config
    assert again.universe == "mine" and again.universe_source.grammar_file == "mine.lark"
    system = parse("Edge0 + Edge0 + Edge0 + Edge0\nEdge0 -> Edge0 [ + Edge1 ] Edge0\nAngle 30\n"
                   "BranchAngle 30\n")
    digests = {grow(system, c.environment).surface.digest() for c in (config, again)}
    assert len(digests) == 1


@pytest.mark.parametrize("data, field", [
    ({"search": {"mode": "nope"}}, "search.mode"),
    ({"search": {"mode": "pareto", "objectives": ["size"]}}, "search.objectives"),
    ({"search": {"mode": "pareto", "objectives": ["size", "wobble"]}}, "search.objectives"),
    ({"search": {"mode": "map-elites", "descriptors": ["wobble"], "ranges": [[0, 1]], "bins": [2]}},
     "search.descriptors"),
    ({"search": {"ranges": [[1, 0], [0, 1]]}}, "search.ranges[0]"),
    ({"search": {"bins": [2]}}, "search.bins"),
    ({"search": {"offspring": 0.0}}, "search.offspring"),
    ({"ea": {"init": "sensible"}}, "ea.init"),
    ({"ea": {"founder_retries": -1}}, "ea.founder_retries"),
    ({"ea": {"unique_retries": 1001}}, "ea.unique_retries"),
    ({"ea": {"unique_redraws": -1}}, "ea.unique_redraws"),
    ({"ea": {"within_used": "yes"}}, "ea.within_used"),
    ({"islands": {"emigrants": "far"}}, "islands.emigrants"),
])
def test_search_settings_refuse_bad_values_naming_the_field(data, field):
    with pytest.raises(ConfigError, match=re.escape(f"field '{field}'")):
        RunConfig.from_dict(data)


def test_search_settings_round_trip_through_toml():
    config = RunConfig.from_dict({"search": {"mode": "map-elites", "descriptors": ["cells", "undulation"],
                                             "ranges": [[1, 33], [0, 2]], "bins": [4, 3]},
                                  "ea": {"init": "ramped", "within_used": True},
                                  "islands": {"emigrants": "best"}})
    assert RunConfig.from_dict(tomllib.loads(config.to_toml())) == config


@pytest.mark.parametrize("name", ["genome", "ea", "islands", "search"])
def test_the_docs_tables_are_the_declared_settings(name):
    """docs/run-config.md's table of each section is ``section_table``'s, drawn from the fields'
    declarations: a field added to a section and not to the docs fails here."""
    from genr8_dist.config import section_table

    doc = (Path(__file__).resolve().parents[1] / "docs" / "run-config.md").read_text(encoding="utf-8")
    after = doc.split(f"section_table('{name}')", 1)[1].split("-->\n", 1)[1]
    assert after.startswith(section_table(name) + "\n\n")


def test_the_docs_top_level_table_is_the_declared_fields():
    """docs/run-config.md's top-level table is ``top_table``'s: a top-level field added to ``RunConfig``
    and not to the docs fails here, and every declared field is a key a file may name."""
    from genr8_dist.config import _TOP_KEYS, top_table

    doc = (Path(__file__).resolve().parents[1] / "docs" / "run-config.md").read_text(encoding="utf-8")
    after = doc.split("top_table()", 1)[1].split("-->\n", 1)[1]
    assert after.startswith(top_table() + "\n\n")
    documented = [row.split("`")[1] for row in top_table().splitlines()[2:]]
    assert documented == ["universe", "seed", "meshing", "environment"]
    assert set(documented) <= set(_TOP_KEYS)


def test_a_declared_bound_may_name_an_earlier_field():
    from genr8_dist.config import EASettings

    assert EASettings(population=4, tournament=4, elites=3).tournament == 4
    with pytest.raises(ConfigError, match=r"field 'ea.tournament': must be <= 4, got 5"):
        EASettings(population=4, tournament=5)
    with pytest.raises(ConfigError, match=r"field 'ea.elites': must be <= 3, got 4"):
        EASettings(population=4, elites=4)
    with pytest.raises(ConfigError, match=r"field 'ea.mutation_rate': must be a number in \[0, 1\]"):
        EASettings(mutation_rate=1.5)
