"""`stringcontact study`'s closing line: the cases' CPU time per rank, or where they ran."""

from stringcontact.cli.study import _cpu_text


def test_the_cpu_clause_is_never_left_empty():
    """`study film` runs its sweep on rank 0 without timing it per rank: its line says so, rather than end in
    "CPU time of the cases per rank: " and nothing."""
    assert _cpu_text([]) == "the cases ran one after another on rank 0"
    assert _cpu_text([1.234, 0.5]) == "CPU time of the cases per rank: 1.23 s, 0.50 s"
