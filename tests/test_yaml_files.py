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


def test_floats_read_by_yaml_1_2s_core_schema(tmp_path):
    """1e-4 and .5e3 are floats (YAML 1.1 wants a dot and a signed exponent), and a base-60
    float is text: `exposure_weight: 1:30.0` was read as 90.0 unsaid (only base-60 integers were
    text); each written back as it reads."""
    text = "a: [1e-4, .5e3, 1., .5, -1.5E+3, 1:30.0, 1:30, -.inf, .NaN, 1_000.5, 10, 0x1e5]\n"
    (tmp_path / "f.yaml").write_text(text)
    numbers = read_yaml(tmp_path / "f.yaml")["a"]
    assert numbers[:5] == [1e-4, 500.0, 1.0, 0.5, -1500.0]
    assert numbers[5:7] == ["1:30.0", "1:30"] and numbers[7] == float("-inf")
    assert numbers[8] != numbers[8] and numbers[9:] == [1000.5, 10, 0x1E5]
    assert [type(n) for n in numbers[9:]] == [float, int, int]
    (tmp_path / "back.yaml").write_text(dump_yaml({"a": numbers}))
    back = read_yaml(tmp_path / "back.yaml")["a"]
    assert back[:8] + back[9:] == numbers[:8] + numbers[9:] and back[8] != back[8]
    # text that reads as a float is written quoted, and a dot alone is text
    texts = {"a": ".5e3", "b": "1e-4", "c": "1.", "d": "."}
    (tmp_path / "texts.yaml").write_text(dump_yaml(texts))
    assert read_yaml(tmp_path / "texts.yaml") == texts


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
