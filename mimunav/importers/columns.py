"""Numeric columns of a logger's files: a CSV (header optional, Excel's `sep=` line, a last
line cut short) or a NumPy array file; and the key check every table-spec level shares."""
import csv
import datetime
import difflib
import glob
import io
import os
import re

import numpy as np

from .recording import RecordingError, text_file

LAYOUT_LINES = 200          # lines a table's layout is read from: comments, header, first data


UTM_NOT_READ = (
    "UTM grid coordinates are [reference] position_utm = {file = ..., columns = [easting, "
    "northing, height], zone = 1-60, hemisphere = \"N\" or \"S\"}, and an attitude in the "
    "grid's axes rotates = \"body_to_utm\"; ")


def check_keys(path, doc, known, where, elsewhere=None):
    """Refuse a key of `doc` not among `known`, naming where it belongs when `elsewhere`
    {key: where it stands} knows it, else the nearest known one."""
    for key in doc:
        if key not in known:
            near = difflib.get_close_matches(key, known, n=1, cutoff=0.5)
            hint = (f"it belongs {elsewhere[key]}; " if elsewhere and key in elsewhere else
                    UTM_NOT_READ if "utm" in key.lower() and key != "position_utm" else
                    f"did you mean {near[0]!r}? " if near else "")
            raise RecordingError(f"{path}: {where} has an unknown key {key!r} ({hint}known: "
                                 f"{', '.join(known)})")


def load_spec(path, columns, notes=None, rows=None):
    """A numeric array from a CSV (header row optional) or a NumPy file (.npy, .npz with one
    array, or an extension-less .npy as comma2k19 stores them) - or from every file a glob
    pattern matches, their rows in the order of their names (KITTI's oxts/data/*.txt, a file
    per epoch). A CSV's last line cut short (a logger stopped mid-write) is left out and said
    in `notes`; any other line whose column count differs is refused. rows {column name:
    text or [texts]}: only the rows whose text in each named column is one of those (a
    logger writing several sensors' rows to one file: Android GnssLogger's MessageType
    UncalAccel, UncalGyro); without it, a file whose rows are of interleaved kinds is
    refused, naming them (its gyro rows had been read as specific force where no two stamps
    collided)."""
    files = files_of(path)
    joined = _joined(files, columns) if len(files) > 1 and rows is None else None
    if joined is not None:
        return joined
    tables = [_load_one(one, notes) for one in files]
    tables = [(data[_rows_where(one, rows, len(data))], names)
              for one, (data, names) in zip(files, tables)]
    widths = [data.shape[1] for data, _ in tables]
    if len(set(widths)) > 1:        # one table split in files: one layout throughout
        odd = min(range(len(files)), key=widths.count)
        raise RecordingError(f"{files[odd]}: {widths[odd]} columns, another column count than "
                             f"{files[0]}'s {widths[0]}: the files of {path} must hold one "
                             "table's columns")
    return np.vstack([_picked(one, data, names, columns)
                      for one, (data, names) in zip(files, tables)])


def _joined(files, columns):
    """The rows of many headerless text tables of one layout (a file per epoch) read as one
    text - 13,000 one-line files read one by one took 5 s a quantity - or None where they
    are not that (a header, a separator line, a NumPy file, a line of another length: then
    each is read on its own, and what is wrong named)."""
    if not all(f.endswith((".csv", ".txt")) for f in files):
        return None
    sep, skip, header = _csv_layout(files[0])
    if header or skip or (columns is not None and any(isinstance(c, str) for c in columns)):
        return None
    parts = []
    for name in files:
        with open(name) as fh, text_file(name):
            text = fh.read()
        parts.append(text if text.endswith("\n") else text + "\n")
    try:
        data = np.genfromtxt(io.StringIO("".join(parts)), delimiter=sep, dtype=float,
                             invalid_raise=True, ndmin=2)
    except ValueError:
        return None
    return data if columns is None else data[:, list(columns)]


def files_of(path):
    """[path], or the files a glob pattern (* ? [) matches, in the order of their names."""
    if not any(c in os.path.basename(path) for c in "*?["):
        return [path]
    found = sorted(glob.glob(path))
    if not found:
        raise RecordingError(f"{path}: no file matches")
    return found


COMPRESSED = (".gz", ".zip", ".xz", ".bz2", ".zst")


def _load_one(path, notes):
    """(the numbers of one file, (N, columns); its header's names, or None)."""
    if not os.path.exists(path):
        raise RecordingError(f"{path}: no such file")
    names = None
    if path.endswith(COMPRESSED):
        raise RecordingError(f"{path}: a compressed file - decompress it (gunzip, unzip, unxz, "
                             "bunzip2) and name the file it holds")
    if path.endswith((".csv", ".txt")):
        sep, skip, header = _csv_layout(path)
        data = _read_csv(path, header, notes, sep, skip)
        if header:                      # the names as written, not as the reader makes them
            data = np.column_stack([data[n] for n in data.dtype.names])
            names = header_names(path, sep, skip)
    else:
        try:
            data = np.load(path, allow_pickle=False)
        except (ValueError, OSError) as exc:
            raise RecordingError(f"{path}: not a NumPy array file ({exc})") from None
        if isinstance(data, np.lib.npyio.NpzFile):
            if len(data.files) != 1:
                raise RecordingError(f"{path}: {len(data.files)} arrays; store one per file")
            data = data[data.files[0]]
    data = np.asarray(data, dtype=float)
    if data.size == 0:
        raise RecordingError(f"{path}: no data rows")
    return data.reshape(len(data), -1), names


KIND_CHANGES = 0.25     # of a layout's rows: a text column that changes this often between
#                         neighbouring rows interleaves kinds of row (a status column runs)


def _rows_where(path, rows, n):
    """The mask of a file's n data rows that `rows` keeps (`load_spec`); all without it, but
    a CSV whose first LAYOUT_LINES rows interleave kinds in a text column is refused."""
    if not path.endswith((".csv", ".txt")):
        if rows:
            raise RecordingError(f"{path}: `rows` picks a CSV's rows by a text column; a "
                                 "NumPy file has none")
        return np.ones(n, bool)
    if not rows:
        _refuse_interleaved(path, *_text_rows(path, LAYOUT_LINES))
        return np.ones(n, bool)
    names, cells = _text_rows(path)
    if not isinstance(rows, dict):
        raise RecordingError(f"{path}: rows {rows!r}: a table {{column name = text or [texts]}}")
    keep = np.ones(len(cells), bool)
    for name, wanted in rows.items():
        k = _row_column(path, names, name)
        wanted = {str(w) for w in (wanted if isinstance(wanted, list) else [wanted])}
        keep &= np.array([k < len(r) and r[k].strip() in wanted for r in cells])
    if len(keep) != n:
        raise RecordingError(f"{path}: {len(keep)} text rows, {n} numeric rows: `rows` cannot "
                             "pick among them")
    if not keep.any():
        raise RecordingError(f"{path}: no row is {rows}" + (
            " - a file of one row (a glob of one file per epoch) cannot drop its epoch by "
            "`rows`: the keys another file gives (its times) would keep it; gather the "
            "epochs into one table first" if len(keep) == 1 else ""))
    return keep


def _row_column(path, names, name):
    """The 0-based index of the column `rows` names by `name`: a header's name, or the
    index itself in digits (a TOML key is text: rows = {"1" = "3"}, a file without a
    header)."""
    if names is not None and name in names:
        return names.index(name)
    if name.isdigit():
        return int(name)
    raise RecordingError(f"{path}: rows: column {name!r} " + (
        f"not among the header's {names}" if names is not None else
        "named, but the file has no header: give its 0-based index, rows = {\"1\" = \"3\"}"))


def _refuse_interleaved(path, names, cells):
    """Refuse a table whose text column (2-8 values) changes between KIND_CHANGES of its
    neighbouring rows: rows of several kinds, each a sensor's, one read as another's."""
    for k, name in enumerate(names or []):
        text = [r[k].strip() for r in cells if k < len(r)]
        if len(text) < 20 or any(_number(x) for x in text):
            continue
        kinds = sorted(set(text))
        if 2 <= len(kinds) <= 8 and \
                sum(a != b for a, b in zip(text, text[1:])) >= KIND_CHANGES * len(text):
            raise RecordingError(
                f"{path}: its rows are of {len(kinds)} kinds interleaved (column {name!r}: "
                f"{', '.join(map(repr, kinds))}), each kind its own quantity: pick one per "
                f"column source with rows = {{{name} = {kinds[0]!r}}}".replace("'", '"'))


def _text_rows(path, limit=None, first_is_data=None):
    """(the header's names or None, the data rows as lists of text cells) of a CSV - its
    first `limit` lines only, when given -, the rows `load_spec` reads: comment lines and a
    last line cut short left out; a header's row is data where first_is_data(its cells)."""
    sep, skip, header = _csv_layout(path)
    with open(path, newline="") as fh, text_file(path):
        lines = fh.readlines()[skip:] if limit is None else \
            [line for _, line in zip(range(skip + limit), fh)][skip:]
    rows = [r for r in (csv.reader(lines, delimiter=sep) if sep else (x.split() for x in lines))
            if any(c.strip() for c in r) and not _commented(r[0])]
    if header and first_is_data is not None and rows and first_is_data(rows[0]):
        header = False
    names = header_names(path, sep, skip) if header else None
    if header and lines and not _commented(lines[0]):
        rows.pop(0)                                 # the header row (a '#' one is left out)
    if rows and len(rows[-1]) != len(rows[0]) and limit is None:
        rows.pop()                                  # cut short (`load_spec` says so)
    return names, rows


def _picked(path, data, names, columns):
    """The `columns` of a file's numbers: header names (a header's '#' no part of one) or
    0-based indices; all for None."""
    if columns is None:
        return data
    if any(isinstance(c, str) for c in columns):
        if names is None:
            raise RecordingError(f"{path}: columns by name need a CSV header")
        try:
            columns = [names.index(c.lstrip("#").strip()) if isinstance(c, str) else c
                       for c in columns]
        except ValueError:
            raise RecordingError(f"{path}: columns {columns} not among {names}") from None
    return data[:, list(columns)]


COMMENT_MARKS = ("#", "//")     # what a comment line starts with (an Xsens export's '//')


def _commented(line):
    """Whether a line (or a row's first cell) of a table is a comment."""
    return line.lstrip().startswith(COMMENT_MARKS)


def _csv_layout(path):
    """(separator - None: runs of whitespace -, lines before the header or data, whether a
    header row names the columns) of a CSV or text table: Excel's `sep=` line, else commas,
    else whitespace when the first data line is whitespace-separated numbers (KITTI's, TUM's
    text tables). Lines starting with '#' or '//' (an Xsens export's) before the data are
    comments; the last of them is the header when it names as many columns as the data has
    ('# timestamp tx ty tz ...'), and a first line that is not all numbers is one too (over
    whitespace-separated numbers, as many names as they have columns: a text table's header
    without its '#')."""
    with open(path) as fh, text_file(path):
        lines = [line for _, line in zip(range(LAYOUT_LINES), fh)]
    sep, skip = ",", 0
    first = lines[0].rstrip("\r\n").strip(" ").strip('"') if lines else ""
    if first.lower().startswith("sep="):     # Excel's separator line (quoted: Consensys's)
        sep = first[4:5] or ","
        if sep not in (",", ";", "\t", "|"):
            raise RecordingError(f"{path}: separator line {lines[0].strip()!r}: one of "
                                 ", ; tab |")
        skip = 1
    k = skip
    while k < len(lines) and (not lines[k].strip() or _commented(lines[k])):
        k += 1
    data = lines[k].strip() if k < len(lines) else ""
    if not skip and "," not in data and len(data.split()) > 1 and \
            all(_number(x) for x in data.split()):
        sep = None
    if sep is not None and not skip and "," not in data and \
            _spaced_numbers(lines[k + 1:], len(data.split())):
        return None, k, True        # a header of names over a text table (GTSAM's KITTI)

    def cells(line):
        return line.split() if sep is None else line.split(sep)
    if not all(_number(x) for x in cells(data)):
        return sep, k, True
    before = lines[k - 1].lstrip() if k > skip else ""
    named = cells(before.lstrip("#/")) if _commented(before) else []
    if len(named) == len(cells(data)) and not all(_number(x) for x in named):
        return sep, k - 1, True
    return sep, k, False


def _spaced_numbers(lines, width):
    """Whether the first of `lines` that holds anything is `width` (> 1) numbers separated
    by whitespace, no comma."""
    first = next((line.strip() for line in lines if line.strip()), "")
    cells = first.split()
    return width > 1 and "," not in first and len(cells) == width and \
        all(_number(x) for x in cells)


def load_date_times(path, column, zone=None, rows=None):
    """`_date_times` of a file, or of every file a glob pattern matches (`files_of`), the
    rows `rows` keeps (`load_spec`)."""
    times = [_date_times(one, column, zone) for one in files_of(path)]
    return np.concatenate([x[_rows_where(one, rows, len(x))]
                           for one, x in zip(files_of(path), times)])


def _date_times(path, column, zone=None):
    """(N,) UNIX time, s, of a CSV column (header name or 0-based index) of ISO 8601
    date-times with their UTC offset ('2023-08-04 17:47:58.125-04:00', '...T21:47:58Z'), the
    rows `load_spec` reads of the same file (a last line cut short left out). A date-time
    without an offset takes `zone` ('Z', '+02:00': its clock's, as the data's documentation
    says), and is refused without one: its time zone is unknown."""
    if not os.path.exists(path):
        raise RecordingError(f"{path}: no such file")
    if not path.endswith((".csv", ".txt")):
        raise RecordingError(f"{path}: date-times are read from a CSV, not a NumPy file")
    names, rows = _text_rows(path, first_is_data=lambda row: isinstance(column, int) and
                             column < len(row) and _date_time(row[column]))
    if isinstance(column, str):
        column = column.lstrip("#").strip()         # a header's '#' is no part of a name
        if names is None or column not in names:
            raise RecordingError(f"{path}: column {column!r} not among {names}")
        column = names.index(column)
    out = np.empty(len(rows))
    for k, row in enumerate(rows):
        text = row[column].strip() if column < len(row) else ""
        try:
            when = datetime.datetime.fromisoformat(text)
        except ValueError:
            raise RecordingError(f"{path}: data row {k}: {text!r} is not an ISO 8601 "
                                 "date-time") from None
        if when.tzinfo is None and zone is None:
            raise RecordingError(f"{path}: data row {k}: {text!r} has no UTC offset ('Z' or "
                                 "+hh:mm): the time zone of its clock is unknown (`zone = "
                                 "\"Z\"` or \"+hh:mm\" in its column source gives it)")
        if when.tzinfo is None:
            when = when.replace(tzinfo=_zone(path, zone))
        out[k] = when.timestamp()
    if not len(out):
        raise RecordingError(f"{path}: no data rows")
    return out


def _date_time(text):
    """Whether a cell reads as an ISO 8601 date-time."""
    try:
        datetime.datetime.fromisoformat(text.strip())
        return True
    except ValueError:
        return False


def _zone(path, zone):
    """The tzinfo of a `zone` text: 'Z' or '+hh:mm' / '-hh:mm'."""
    try:
        tz = datetime.datetime.fromisoformat("2000-01-01T00:00:00" + str(zone)).tzinfo
    except ValueError:
        tz = None
    if tz is None:
        raise RecordingError(f"{path}: zone {zone!r}: 'Z' or a UTC offset such as '+02:00'")
    return tz


def _number(text):
    """Whether a CSV cell reads as a number ('nan', 'inf' and empty do: a first row of data
    with a missing reading is no header)."""
    try:
        float(text or "nan")
        return True
    except ValueError:
        return False


def header_names(path, sep, skip):
    """A CSV's column names as its header row writes them, after `skip` lines: spaces around
    each and a comment mark before the first left out ('#timestamp [ns]' is EuRoC's first);
    sep None: separated by whitespace."""
    with open(path, newline="") as fh, text_file(path):
        for _ in range(skip):
            fh.readline()
        line = fh.readline()
    if sep is None:
        names = line.lstrip().lstrip("#").split()
    else:
        names = [c.strip() for c in next(csv.reader([line], delimiter=sep))]
    if names:
        names[0] = names[0].lstrip("#").strip()
    return names


def _names_filled(path, sep, skip):
    """The CSV for the reader: its path, or its lines with the header's (line `skip`) empty
    names written c0, c1, ... - the reader drops an empty name, and pandas' index column
    (a header's empty first cell) had made every line 'another column count than the
    first'."""
    names = header_names(path, sep, skip)
    if all(names):
        return path
    with open(path) as fh, text_file(path):
        lines = fh.readlines()
    lines[skip] = (sep or " ").join(n or f"c{k}" for k, n in enumerate(names)) + "\n"
    return lines


def _read_csv(path, header, notes, sep=",", skip=0):
    """The numbers of a CSV after `skip` lines: a structured array named by its header row
    when it has one (the reader's names, which `header_names` corrects), else (N, columns)."""
    source = _names_filled(path, sep, skip) if header else path
    read = lambda **kw: np.genfromtxt(source, delimiter=sep, names=True if header else None,  # noqa: E731
                                      dtype=float, invalid_raise=True, skip_header=skip,
                                      ndmin=0 if header else 2, **kw)
    try:
        return read()
    except ValueError as exc:
        bad = [int(n) for n in re.findall(r"Line #(\d+)", str(exc))]
        if not bad:
            raise RecordingError(f"{path}: not a numeric CSV ({str(exc).strip()[:120]})") from None
        with open(path, "rb") as fh:
            last = sum(1 for line in fh if line.strip())
        if bad != [last]:
            raise RecordingError(f"{path}: line(s) {', '.join(map(str, bad[:5]))} have another "
                                 "column count than the first; a table needs the same columns "
                                 "on every line") from None
    if notes is not None:
        notes[f"{os.path.basename(path)}"] = f"its last line (#{last}) was cut short: left out"
    return read(skip_footer=1)
