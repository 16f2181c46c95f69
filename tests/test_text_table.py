"""The aligned text tables of the demo, sim-train and the benchmarks (text_table.py)."""

import pytest
from spikegs.text_table import column_format, print_table


def test_a_columns_floats_share_their_decimals(capsys):
    """sim-train's PSNRs printed as 43.1, 37.12 and 40 (4 significant digits each): a column
    reads to the decimals of its largest value's 4 digits; a column of numbers too small for
    fixed decimals (1e-05 would be 0.0000), or spanning a factor 1000 or more (0.0123 beside 2500
    would be 0), keeps 4 significant digits each."""
    rows = [
        {"method": "SIM", "psnr": 43.1, "ssim": 0.99123, "tiny": 1e-5, "ms": 0.0123, "n": 3},
        {"method": "TFP(33)", "psnr": 37.1234, "ssim": 0.912, "tiny": 0.5, "ms": 150.0, "n": 12},
        {"method": "TFI", "psnr": 40.0045, "ssim": float("nan"), "tiny": 2.0, "ms": 2500.0, "n": 7},
    ]
    print_table(rows)
    assert capsys.readouterr().out.splitlines() == [
        " method   psnr    ssim   tiny      ms   n",
        "    SIM  43.10  0.9912  1e-05  0.0123   3",
        "TFP(33)  37.12  0.9120    0.5     150  12",
        "    TFI  40.00     nan      2    2500   7",
    ]


def test_fixed_decimals_only_within_their_range_and_headers_set_the_width(capsys):
    """Decimals for a column's largest value (43.1 beside 5.2: 2, not 3 for 5.2); below 0.001
    (0.0005) or from 1e6 up (2e6) 4 significant digits (0.0005000 and 2000000 were printed); a
    0 takes no part (0.0 beside 43.1 read 0 and 43.1); a header wider than its values sets the
    column's width."""
    rows = [
        {"a_long_header": 0.0005, "mega": 2e6, "psnr": 43.1, "zero": 0.0},
        {"a_long_header": 0.0007, "mega": 3e6, "psnr": 5.2, "zero": 43.1},
    ]
    print_table(rows)
    assert capsys.readouterr().out.splitlines() == [
        "a_long_header   mega   psnr   zero",
        "       0.0005  2e+06  43.10   0.00",
        "       0.0007  3e+06   5.20  43.10",
    ]


@pytest.mark.parametrize(
    "values, spec",
    [
        ([0.001], ".6f"),  # the range's ends: 0.001 in, 1e6 out
        ([0.00099], ".4g"),
        ([999999.0], ".0f"),
        ([1e6], ".4g"),
        ([1.0, 999.0], ".1f"),  # within a factor 1000, and at it
        ([1.0, 1000.0], ".4g"),
        ([-2.0, 1999.0], ".0f"),  # sizes: signs take no part
        ([-2.0, -2000.0], ".4g"),
    ],
)
def test_fixed_decimals_hold_up_to_each_end_of_their_range(values, spec):
    assert column_format(values) == spec


def test_no_rows_print_nothing(capsys):
    """A table of no rows prints nothing (not an IndexError on its first row), with or without
    the columns named."""
    print_table([])
    print_table([], ["method", "psnr"])
    assert capsys.readouterr().out == ""


def test_columns_are_the_first_rows_keys(capsys):
    """Without columns named, a table's columns are its first row's keys (a one-row table has
    no second row to read them from): a later row's key the first lacks is not printed, one it
    lacks prints empty."""
    print_table([{"method": "SIM", "psnr": 43.1}])
    print_table([{"method": "SIM", "psnr": 43.1}, {"method": "TFI", "ssim": 0.9}])
    assert capsys.readouterr().out.splitlines() == [
        "method   psnr",
        "   SIM  43.10",
        "method   psnr",
        "   SIM  43.10",
        "   TFI       ",
    ]
