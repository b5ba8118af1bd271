"""Scratch files of the sensor level for a flight too long to hold (`samples`, `design`):
per-sample columns appended block by block and read back a column or a span of rows at a
time (`Spill`, `Columns`), and a channel's design matrix kept the same way (`ScratchMatrix`):
filled a block of bins at a time, read a block of rows (`wander.grams`) or a term's columns
(`design.TermColumns`) at a time, so that its memory is one block's, not the flight's."""
import tempfile
from pathlib import Path

import numpy as np


class Spill:
    """Per-sample columns appended block by block and read back a column or a span of rows
    at a time: held in memory (folder None: a single block's arrays are kept as they are,
    without a copy), else in `folder`, one file of raw values per column."""

    def __init__(self, folder=None):
        self.folder = None if folder is None else Path(folder)
        self._parts, self._kinds, self._files = {}, {}, {}

    def __contains__(self, name):
        return name in self._kinds

    def append(self, name, x):
        """Append rows x (n,) or (n, k) to column group `name`."""
        x = np.asarray(x)
        kind, new = (x.dtype, x.shape[1:]), name not in self._kinds
        if self._kinds.setdefault(name, kind) != kind:
            raise ValueError(f"{name}: rows of {kind}, not {self._kinds[name]}")
        if self.folder is None:
            self._parts.setdefault(name, []).append(x)
            return
        cols = x.reshape(len(x), -1)
        for c in range(cols.shape[1]):
            if (name, c) not in self._files:    # a new group's file replaces an earlier
                # Spill's; one closed since (`close`, `put_column`) is appended to
                self._files[(name, c)] = open(self._path(name, c), "wb" if new else "ab")
            self._files[(name, c)].write(np.ascontiguousarray(cols[:, c]).tobytes())

    def put_column(self, name, c, x):
        """Replace column c of group `name` (in files) by x (N,), the same length."""
        self._flush()
        if len(x) * self._kinds[name][0].itemsize != self._path(name, c).stat().st_size:
            raise ValueError(f"{name}.{c}: {len(x)} rows replace a column of another length")
        self._files.pop((name, c)).close()
        np.ascontiguousarray(x, self._kinds[name][0]).tofile(self._path(name, c))

    def close(self):
        """Flush and close the scratch files (they stay readable)."""
        for fh in self._files.values():
            fh.close()
        self._files = {}

    def column(self, name, c=None):
        """(N,) column c of group `name` (c None: a group of single columns)."""
        if self.folder is None:
            x = self._held(name)
            return x if c is None else x[:, c]
        self._flush()
        return np.fromfile(self._path(name, c or 0), self._kinds[name][0])

    def span(self, name, a, b):
        """Rows a..b-1 of group `name`, (b - a,) or (b - a, k)."""
        if self.folder is None:
            return self._held(name)[a:b]
        self._flush()
        dtype, shape = self._kinds[name]
        width = int(np.prod(shape)) if shape else 1
        out = np.empty((b - a, width), dtype)
        for c in range(width):
            out[:, c] = np.fromfile(self._path(name, c), dtype, count=b - a,
                                    offset=a * dtype.itemsize)
        return out.reshape((b - a,) + shape)

    def count(self, name):
        """The rows of group `name` so far."""
        if name not in self._kinds:
            return 0
        if self.folder is None:
            return len(self._held(name))
        self._flush()
        return self._path(name, 0).stat().st_size // self._kinds[name][0].itemsize

    def series(self, name):
        """Group `name` as something read as x[:, c]: the array when held, else `Columns`."""
        return self._held(name) if self.folder is None else Columns(self, name)

    def _held(self, name):
        parts = self._parts[name]
        if len(parts) > 1:
            self._parts[name] = parts = [np.concatenate(parts)]
        return parts[0]

    def _path(self, name, c):
        return self.folder / f"{name}.{c}"

    def _flush(self):
        for fh in self._files.values():
            fh.flush()


class Columns:
    """A spilled (N, k) group read one column at a time: x[:, c]."""

    def __init__(self, spill, name):
        self.spill, self.name = spill, name

    def __getitem__(self, key):
        rows, c = key
        if rows != slice(None):
            raise IndexError("a spilled group is read a whole column at a time: x[:, c]")
        return self.spill.column(self.name, c)




class ScratchMatrix:
    """An (n, k) float64 matrix in scratch files, a column a file (single-column groups of a
    `Spill`), filled a block of rows at a time in order (`append`) and read as x[a:b] (rows
    a..b-1, every column) or x[:, a:b] (columns a..b-1, every row); `selected` takes rows and
    columns without moving data. The scratch folder is removed when the last matrix reading
    it is released (or the process ends)."""

    def __init__(self, spill, names, scratch, rows=None):
        self._spill, self._names, self._scratch = spill, list(names), scratch
        self._rows = rows       # the file rows of this matrix's rows (None: every row)

    @classmethod
    def empty(cls, spill, scratch, prefix, k):
        """A matrix of k columns and no rows, its files `prefix`.i in `spill`'s folder."""
        return cls(spill, [f"{prefix}.{i}" for i in range(k)], scratch)

    @staticmethod
    def scratch():
        """(a `Spill` in a new scratch folder, the folder's handle to keep alive)."""
        folder = tempfile.TemporaryDirectory(prefix="mimunav-design-")
        return Spill(folder.name), folder

    @property
    def shape(self):
        n = self._spill.count(self._names[0]) if self._rows is None else len(self._rows)
        return n, len(self._names)

    def __len__(self):
        return self.shape[0]

    def append(self, rows):
        """Append rows (m, k) at the end (a matrix that selects nothing)."""
        if self._rows is not None or rows.shape[1] != len(self._names):
            raise ValueError(f"{rows.shape} rows appended to a {self.shape} scratch matrix "
                             "(a selection is read-only)")
        for name, x in zip(self._names, rows.T):
            self._spill.append(name, np.ascontiguousarray(x, float))

    def widened(self, first, k):
        """This matrix with k more columns at the end, copies of columns first..first+k-1 so
        far (`samples._part`)."""
        prefix = self._names[0].rsplit(".", 1)[0]
        names = [f"{prefix}.{len(self._names) + i}" for i in range(k)]
        for name, source in zip(names, self._names[first:first + k]):
            if self._spill.count(source):
                self._spill.append(name, self._spill.column(source))
        return ScratchMatrix(self._spill, self._names + names, self._scratch)

    def selected(self, rows, cols):
        """The matrix of rows `rows` ((n,) bool) and columns `cols` (indices), reading the
        same files."""
        kept = np.flatnonzero(rows)
        return ScratchMatrix(self._spill, [self._names[c] for c in cols], self._scratch,
                             kept if self._rows is None else self._rows[kept])

    def close(self):
        """Flush and close the files being written (they stay readable)."""
        self._spill.close()

    def __getitem__(self, key):
        if isinstance(key, slice) and key.step in (None, 1):
            return self._read_rows(*key.indices(len(self))[:2])
        if not (isinstance(key, tuple) and len(key) == 2 and isinstance(key[0], slice)
                and key[0] == slice(None) and isinstance(key[1], slice)):
            raise IndexError("a scratch matrix is read as x[a:b] or x[:, a:b]")
        names = self._names[key[1]]
        out = np.empty((len(self), len(names)))
        for i, name in enumerate(names):
            x = self._spill.column(name)
            out[:, i] = x if self._rows is None else x[self._rows]
        return out

    def _read_rows(self, a, b):
        out = np.empty((max(b - a, 0), len(self._names)))
        if not len(out):
            return out
        rows = None if self._rows is None else self._rows[a:b]
        lo, hi = (a, b) if rows is None else (int(rows[0]), int(rows[-1]) + 1)
        for i, name in enumerate(self._names):
            x = self._spill.span(name, lo, hi)
            out[:, i] = x if rows is None else x[rows - lo]
        return out
