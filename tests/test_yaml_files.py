"""yaml_files.py: YAML 1.2's integers, which PyYAML's YAML 1.1 reads otherwise."""

import pytest
import yaml
from spikegs.yaml_files import dump_yaml, read_yaml


def test_integers_read_by_yaml_1_2s_core_schema(tmp_path):
    """Signed decimals (leading zeros decimal, 1.1's octal), 0o octal and 0x hexadecimal (in
    1.2 unsigned: a sign makes them text), underscores dropped; each written back as it reads."""
    (tmp_path / "n.yaml").write_text("a: [-12, +7, -020, 0o17, 0x1F, 0xff, 1_000, 0, -0o17]\n")
    numbers = read_yaml(tmp_path / "n.yaml")
    assert numbers == {"a": [-12, 7, -20, 15, 31, 255, 1000, 0, "-0o17"]}
    (tmp_path / "back.yaml").write_text(dump_yaml(numbers))
    assert read_yaml(tmp_path / "back.yaml") == numbers


def test_one_document_with_empty_ones_around_it(tmp_path):
    """A closing or doubled `---` leaves the file's one document (it was refused as a second);
    two documents are refused, an empty file is None."""
    for text in ("a: 1\n---\n", "---\na: 1\n---\n---\n", "---\n---\na: 1\n...\n"):
        (tmp_path / "one.yaml").write_text(text)
        assert read_yaml(tmp_path / "one.yaml") == {"a": 1}, text
    (tmp_path / "two.yaml").write_text("a: 1\n---\nb: 2\n")
    with pytest.raises(yaml.YAMLError, match=r"^2 YAML documents \(split by ---\): expected one"):
        read_yaml(tmp_path / "two.yaml")
    for text in ("", "---\n", "# nothing\n"):
        (tmp_path / "none.yaml").write_text(text)
        assert read_yaml(tmp_path / "none.yaml") is None, text
