"""yaml_files.py: YAML 1.2's integers, which PyYAML's YAML 1.1 reads otherwise."""

from spikegs.yaml_files import dump_yaml, read_yaml


def test_integers_read_by_yaml_1_2s_core_schema(tmp_path):
    """Signed decimals (leading zeros decimal, 1.1's octal), 0o octal and 0x hexadecimal (in
    1.2 unsigned: a sign makes them text), underscores dropped; each written back as it reads."""
    (tmp_path / "n.yaml").write_text("a: [-12, +7, -020, 0o17, 0x1F, 0xff, 1_000, 0, -0o17]\n")
    numbers = read_yaml(tmp_path / "n.yaml")
    assert numbers == {"a": [-12, 7, -20, 15, 31, 255, 1000, 0, "-0o17"]}
    (tmp_path / "back.yaml").write_text(dump_yaml(numbers))
    assert read_yaml(tmp_path / "back.yaml") == numbers
