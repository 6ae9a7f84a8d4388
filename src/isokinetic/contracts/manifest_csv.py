"""The manifest's ``csv`` block (docs/raw-campaign-format.md, "The csv block"): how a campaign's case files are
written, parsed to a :class:`isokinetic.rawfile.FileFormat`, and the near-miss check of unknown keys.

Format 1.1: ``delimiter`` and ``decimal``; 1.2: ``format`` (``mts793``), ``encoding``, ``units_row``; 1.4:
``header`` (``none``: a headerless file, columns named by position), ``format: xlsx`` and ``sheet`` (a
spreadsheet export); 1.5: ``thousands`` (a thousands separator: ``.`` ``,`` a space or ``'``) and ``timezone`` (the
zone of local ISO 8601 stamps, an IANA name). A malformed block refuses the campaign (:class:`ManifestError`),
naming the key. Split from :mod:`isokinetic.contracts.manifest`, which re-exports these names.
"""

from __future__ import annotations

import codecs
import difflib
from collections.abc import Mapping

from isokinetic.contracts.manifest_yaml import ManifestError
from isokinetic.rawfile import FORMATS as FILE_FORMATS
from isokinetic.rawfile import THOUSANDS, FileFormat

#: How alike (difflib ratio, lower case) an unknown key must be to a known one to be warned about as a slip.
NEAR_MISS_RATIO = 0.8
#: Field delimiters a manifest's ``csv`` block (format 1.1) may declare, with the words used in messages.
CSV_DELIMITERS = {",": "','", ";": "';'", "\t": "tabs", "|": "'|'"}
#: Spellings of the tab delimiter besides a real tab (YAML ``"\t"``): ``'\t'`` in single quotes (a
#: backslash and a t, the usual slip) and the word ``tab``.
CSV_TAB_SPELLINGS = ("\\t", "tab")
#: Decimal marks a ``csv`` block may declare.
CSV_DECIMALS = (".", ",")
#: A csv block's ``header`` (1.4): a header row (after any preamble), or none (columns named by position).
HEADER_KINDS = ("row", "none")
CSV_KEYS = ("format", "delimiter", "decimal", "encoding", "units_row", "header", "sheet",     # header, sheet: 1.4
            "thousands", "timezone")                                                        # 1.5
#: The case files' format declared by a manifest's ``csv`` block: :class:`isokinetic.rawfile.FileFormat`
#: (format 1.1: delimiter and decimal mark; 1.2: format, encoding, units row).
CsvDialect = FileFormat


def near_miss(key, known) -> str | None:
    """The known key an unknown ``key`` is probably a slip for (difflib, case ignored), or None."""
    if not isinstance(key, str) or key in known:
        return None
    lowered = {k.lower(): k for k in known}
    if key.lower() in lowered:
        return lowered[key.lower()]
    match = difflib.get_close_matches(key.lower(), list(lowered), n=1, cutoff=NEAR_MISS_RATIO)
    return lowered[match[0]] if match else None


def near_miss_warnings(where: str, entries: Mapping, known, prefix: str = "") -> list[str]:
    """One warning per key of ``entries`` that is not in ``known`` but close to a key that is."""
    out = []
    for key in entries:
        meant = near_miss(key, known)
        if meant is not None:
            out.append(f"{where}: key {prefix + str(key)!r} is not a key of the format, kept as metadata; "
                       f"did you mean {meant!r}?")
    return out


def _csv_delimiter(value, where: str) -> str:
    if isinstance(value, str) and value.strip().lower() in CSV_TAB_SPELLINGS:
        return "\t"
    if isinstance(value, str) and value.strip().lower() == "whitespace":
        return "whitespace"
    if not isinstance(value, str) or value not in CSV_DELIMITERS:
        raise ManifestError(where, "csv.delimiter", f"must be one of ',', ';', \"\\t\" (tab), '|' or whitespace, "
                                                    f"got {value!r}")
    return value


def _csv_encoding(value, where: str) -> str:
    """A Python codec name (``codecs.lookup``), as written."""
    if not isinstance(value, str) or not value.strip():
        raise ManifestError(where, "csv.encoding", f"must be a text encoding name (utf-8, cp1252, latin-1, utf-16, "
                                                   f"...), got {value!r}")
    try:
        info = codecs.lookup(value.strip())
    except LookupError:
        raise ManifestError(where, "csv.encoding", f"unknown encoding {value!r} (for example utf-8, cp1252, latin-1, "
                                                   "utf-16)") from None
    if not info._is_text_encoding:
        raise ManifestError(where, "csv.encoding", f"{value!r} is not a text encoding")
    return value.strip()


def csv_dialect(block, where: str) -> CsvDialect | None:
    """The optional ``csv`` block, e.g. ``{delimiter: ";", decimal: ","}`` (format 1.1) or ``{format: mts793,
    encoding: cp1252}`` (1.2 additions); None when absent.

    Any key may be left out (defaults: delimited, ',', '.', utf-8, no units row). The tab delimiter is written
    ``"\\t"`` (double quotes), ``'\\t'`` or ``tab``; ``whitespace`` splits on runs of blanks. Refused as a broken
    manifest, naming the key: a block that is not a mapping, a key not in :data:`CSV_KEYS` (a ``thousands`` key
    would otherwise be silently ignored), a format not in :data:`isokinetic.rawfile.FORMATS`, a delimiter not in
    :data:`CSV_DELIMITERS` (or whitespace), a decimal mark not in :data:`CSV_DECIMALS`, the same character for
    both, an encoding ``codecs.lookup`` does not know, a ``units_row`` that is not true/false. An ``mts793``
    file's delimiter (tab or whitespace) and decimal mark are the file's own: a delimiter declared with it must
    be tab or whitespace.
    """
    if block is None:
        return None
    if not isinstance(block, Mapping):
        raise ManifestError(where, "csv", f"expected a mapping with keys {', '.join(CSV_KEYS)}, got {block!r}")
    unknown = [k for k in block if k not in CSV_KEYS]
    if unknown:
        meant = near_miss(unknown[0], CSV_KEYS)
        raise ManifestError(where, f"csv.{unknown[0]}", f"unknown key: the csv block declares only "
                                                        f"{', '.join(CSV_KEYS)} (ingest reads nothing else)"
                            + (f"; did you mean {meant!r}?" if meant else ""))
    fmt = block.get("format", "delimited")
    if fmt not in FILE_FORMATS:
        raise ManifestError(where, "csv.format", f"must be one of {', '.join(FILE_FORMATS)}, got {fmt!r}")
    delimiter = _csv_delimiter(block.get("delimiter", "\t" if fmt == "mts793" else ","), where)
    if fmt == "mts793" and delimiter not in ("\t", "whitespace"):
        raise ManifestError(where, "csv.delimiter", f"an mts793 export is tab or whitespace separated, "
                                                    f"got {delimiter!r}")
    decimal = block.get("decimal", ".")
    if decimal not in CSV_DECIMALS:
        raise ManifestError(where, "csv.decimal", f"must be '.' or ',', got {decimal!r}")
    if delimiter == decimal:
        raise ManifestError(where, "csv", f"delimiter and decimal mark are both {decimal!r}: numbers could not be "
                                          "told from fields (a decimal comma needs another delimiter, e.g. ';')")
    encoding = _csv_encoding(block.get("encoding", "utf-8"), where)
    units_row = block.get("units_row", fmt == "mts793")
    if not isinstance(units_row, bool):
        raise ManifestError(where, "csv.units_row", f"must be true or false, got {units_row!r}")
    if fmt == "mts793" and not units_row:
        raise ManifestError(where, "csv.units_row", "an mts793 export always has a units row")
    header, sheet = _csv_layout(block, fmt, units_row, where)
    return FileFormat(format=fmt, delimiter=delimiter, decimal=decimal, encoding=encoding, units_row=units_row,
                      header=header, sheet=sheet, thousands=_csv_thousands(block, delimiter, decimal, where),
                      timezone=_csv_timezone(block.get("timezone"), where))


def _csv_thousands(block: Mapping, delimiter: str, decimal: str, where: str) -> str | None:
    """The csv block's ``thousands`` (1.5): a separator of :data:`isokinetic.rawfile.THOUSANDS` (``space`` spells a
    space), neither the decimal mark nor the delimiter; None when absent."""
    value = block.get("thousands")
    if value is None:
        return None
    value = " " if value == "space" else value
    if value not in THOUSANDS:
        raise ManifestError(where, "csv.thousands", f"must be one of '.', ',', space or \"'\", got {value!r}")
    if value in (decimal, delimiter):
        what = "decimal mark" if value == decimal else "delimiter"
        raise ManifestError(where, "csv.thousands", f"{value!r} is the {what}: a thousands separator must be another "
                                                    "character")
    return value


def _csv_timezone(value, where: str) -> str | None:
    """The csv block's ``timezone`` (1.5): the IANA zone local ISO 8601 stamps were written in; None when absent."""
    if value is None:
        return None
    import zoneinfo

    try:
        zoneinfo.ZoneInfo(str(value).strip())
    except (zoneinfo.ZoneInfoNotFoundError, ValueError):
        raise ManifestError(where, "csv.timezone", f"unknown time zone {value!r}: give an IANA name (Europe/Berlin, "
                                                   "America/Chicago, UTC)") from None
    return str(value).strip()


def _csv_layout(block: Mapping, fmt: str, units_row: bool, where: str) -> tuple[str, str | None]:
    """The csv block's ``header`` (1.4: ``row``, the default, or ``none``: a headerless file whose columns are
    named by position; YAML's true/false mean row/none) and ``sheet`` (1.4: the worksheet of an ``xlsx`` file,
    None: its first). A spreadsheet has no delimiter, decimal mark or encoding to declare."""
    header = block.get("header", "row")
    header = {True: "row", False: "none"}.get(header, header) if isinstance(header, bool) else header
    if header not in HEADER_KINDS:
        raise ManifestError(where, "csv.header", f"must be row or none (a headerless file), got {header!r}")
    if header == "none" and (units_row or fmt == "mts793"):
        raise ManifestError(where, "csv.header", "a headerless file has no units row (and an mts793 export always "
                                                 "has a header): give each column's unit in columns")
    sheet = block.get("sheet")
    if sheet is not None and fmt != "xlsx":
        raise ManifestError(where, "csv.sheet", f"names a worksheet of an xlsx file; the format is {fmt!r}")
    if sheet is not None and (not isinstance(sheet, str) or not sheet.strip()):
        raise ManifestError(where, "csv.sheet", f"must be a worksheet's name, got {sheet!r}")
    if fmt == "xlsx":
        extra = [k for k in ("delimiter", "decimal", "encoding", "thousands") if k in block]
        if extra:
            raise ManifestError(where, f"csv.{extra[0]}", "an xlsx workbook has no delimiter, decimal mark or "
                                                          "encoding: leave the key out")
    return header, None if sheet is None else sheet.strip()
