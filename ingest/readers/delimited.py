"""Tab-separated rows of numbers, read by pyarrow's CSV reader (one thread).

The marker and storage readers (`trc`, `mot`) try this first: on Camargo's trial it reads the
2.3 MB .trc in 10 ms against 13.5 ms for pandas' C parser, and the GRF .mot's force and centre of
pressure columns (37 of 55) in 2.4 ms against 4 ms for the whole table, with the same float values.
It is strict: every row must hold exactly the header's cells, every cell a number or empty (NaN),
no quoting (a quote in a header line cannot join lines).
Anything else returns None, and the caller reads the file with pandas, which names the problem.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np
import pyarrow as pa
from pyarrow import csv

# Searched instead of stripping a file's body (each strip copies a table of a few hundred kB).
NON_SPACE, NON_NEWLINE = re.compile(rb"\S"), re.compile(rb"[^\r\n]")


def strict_float_rows(text: bytes | memoryview, width: int, keep: Sequence[int] | None = None,
                      skip_rows: int = 0) -> np.ndarray | None:
    """The tab-separated rows of `text` after its first `skip_rows` lines (blank lines skipped) as an
    (n, len(keep)) float array of the cells `keep` (default: all `width`), or None when a row does
    not hold `width` cells or a kept cell is neither a number nor empty. Cells not kept are not
    converted, nor checked."""
    names = [str(j) for j in range(width)]
    kept = [names[j] for j in (range(width) if keep is None else keep)]
    try:
        table = csv.read_csv(
            pa.py_buffer(text),
            read_options=csv.ReadOptions(skip_rows=skip_rows, column_names=names, use_threads=False,
                                         block_size=max(len(text), 1 << 20)),
            parse_options=csv.ParseOptions(delimiter="\t", quote_char=False),  # lines are rows
            convert_options=csv.ConvertOptions(include_columns=kept,
                                               column_types=dict.fromkeys(kept, pa.float64())))
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
        return None
    data = np.empty((table.num_rows, len(kept)))
    for j, column in enumerate(table.columns):
        data[:, j] = column.to_numpy()
    return data
