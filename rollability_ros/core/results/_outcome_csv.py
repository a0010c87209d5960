"""CSV files of hand-recorded launch outcomes: strict import and a matching export.

The schema is documented in ``docs/outcome-csv.md``. The import is all or nothing: every bad row is reported
with its line number and the reason, and a file with any bad row is refused as a whole, so no outcome is
silently dropped and no value is guessed. Stdlib only (runs on the robot computer).
"""
import csv
import math
import os
import typing
import unicodedata

from rollability_ros.core.records import (CONTINUOUS_OUTCOMES, NO_SEED, NOT_MEASURED, UNKNOWN_ORIENTATION,
                                          LaunchCondition, LaunchOutcome, check_continuous_outcome, trial_id_for)

#: Columns every file must have.
REQUIRED_COLUMNS = ("configuration", "height_m", "speed_mps", "angle_deg", "repetition", "upright")
#: Orientation columns: all four or none.
ORIENTATION_COLUMNS = ("final_qx", "final_qy", "final_qz", "final_qw")
#: Columns a file may have; a missing one takes the documented default.
OPTIONAL_COLUMNS = ("run_id", "trial_id", "backend", "travel_time_s", "measured_speed_mps",
                    "speed_out_of_tolerance", "classified_by", "note", "stamp_s") + ORIENTATION_COLUMNS + (
                        "seed",) + tuple(CONTINUOUS_OUTCOMES)
#: Column order of exported files.
EXPORT_COLUMNS = ("run_id", "trial_id") + REQUIRED_COLUMNS + OPTIONAL_COLUMNS[2:]

#: Characters a free-text cell (``note``) may hold though they are control characters: a note's tab or line break.
_TEXT_LAYOUT = "\t\n\r"

_TRUE = ("true", "1", "yes", "y")
_FALSE = ("false", "0", "no", "n")


class OutcomeCsvError(ValueError):
    """A CSV file was refused; ``problems`` lists ``(line number, reason)`` for every bad row or header."""

    def __init__(self, path, problems):
        self.path = path
        self.problems = problems
        if len(problems) == 1:   # one problem, one line: the file, the line and the reason (which names the column)
            super().__init__(f"{path}: refused, nothing imported: line {problems[0][0]}: {problems[0][1]}")
            return
        listing = "\n".join(f"  line {line}: {reason}" for line, reason in problems)
        super().__init__(f"{path}: refused, {len(problems)} problem(s); nothing imported:\n{listing}")


def _check_control(text, column):
    """``ValueError`` for a cell holding a control character (a NUL, an escape, a unit separator): ``A\\x00`` would
    be a configuration of its own and ``true\\x1f`` reads as true once stripped. Tab and line breaks are allowed
    around any cell (trimmed as whitespace) and inside ``note``; anywhere else they are refused too."""
    allowed = _TEXT_LAYOUT if column == "note" else ""
    if any(unicodedata.category(c) == "Cc" and c not in allowed for c in text.strip(" " + _TEXT_LAYOUT)):
        raise ValueError(f"{column} must not hold control characters, got {text!r}")


def _parse_bool(text, column):
    value = text.strip().lower()
    if value in _TRUE:
        return True
    if value in _FALSE:
        return False
    raise ValueError(f"{column} must be one of {'/'.join(_TRUE)} or {'/'.join(_FALSE)}, got {text!r}")


def _plain_number(text, column, kind):
    """``ValueError`` for a cell Python's own parser would read but a person did not type as a number: a digit
    separator (``0.7_5`` reads 0.75) or a digit outside ASCII (an Arabic-Indic three reads 3)."""
    if "_" in text or not text.isascii():
        raise ValueError(f"{column} must be {kind} in plain digits, got {text!r}")


def _parse_float(text, column, allow_empty=False):
    if allow_empty and not text.strip():
        return NOT_MEASURED
    _plain_number(text, column, "a number")
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{column} must be a number, got {text!r}") from None
    if not math.isfinite(value):
        raise ValueError(f"{column} must be finite, got {text!r}")
    return value


def _parse_int(text, column):
    _plain_number(text, column, "a whole number")
    try:
        return int(text.strip())
    except ValueError:
        raise ValueError(f"{column} must be a whole number, got {text!r}") from None


def _parse_seed(text, column):
    """A twin seed (integer >= 0); an empty cell or -1 is no seed (a physical launch, a file without seeds)."""
    if not text.strip():
        return NO_SEED
    seed = _parse_int(text, column)
    if seed < NO_SEED:
        raise ValueError(f"{column} must be a twin seed >= 0, or empty for none, got {text!r}")
    return seed


def _parse_continuous(text, column):
    """A continuous outcome: an empty cell is not measured; else a finite number in its range (``nan`` refused)."""
    if not text.strip():
        return NOT_MEASURED
    low, high = CONTINUOUS_OUTCOMES[column]
    return check_continuous_outcome(column, _parse_float(text, column), low, high)


def _parse_row(values, run_id):
    """Build a LaunchOutcome from one row's ``{column: text}``; raise ValueError with every reason."""
    reasons = []

    def field(column: str, parse: typing.Callable[..., typing.Any], default: typing.Any = None,
              *args: typing.Any) -> typing.Any:
        if column not in values:
            return default
        try:
            _check_control(values[column], column)
            return parse(values[column], column, *args)
        except ValueError as exc:
            reasons.append(str(exc))
            return default

    def text(value: str, column: str) -> str:
        return value

    def non_empty(value: str, column: str) -> str:
        if not value.strip():
            raise ValueError(f"{column} must not be empty")
        return value.strip()

    condition_values = {
        "configuration": field("configuration", non_empty),
        "height_m": field("height_m", _parse_float),
        "speed_mps": field("speed_mps", _parse_float),
        "angle_deg": field("angle_deg", _parse_float),
        "repetition": field("repetition", _parse_int),
    }
    upright = field("upright", _parse_bool)
    optional = {
        "run_id": field("run_id", non_empty, run_id),
        "backend": field("backend", non_empty, "physical"),
        "travel_time_s": field("travel_time_s", _parse_float, math.nan, True),
        "measured_speed_mps": field("measured_speed_mps", _parse_float, math.nan, True),
        "speed_out_of_tolerance": field("speed_out_of_tolerance", _parse_bool, False),
        "classified_by": field("classified_by", non_empty, "operator"),
        "note": field("note", text, ""),
        "stamp_s": field("stamp_s", _parse_float, 0.0),
        "seed": field("seed", _parse_seed, NO_SEED),
        **{name: field(name, _parse_continuous, NOT_MEASURED) for name in CONTINUOUS_OUTCOMES},
    }
    optional["final_orientation"] = UNKNOWN_ORIENTATION   # hand-recorded: no sensor saw it
    if ORIENTATION_COLUMNS[0] in values:
        # empty cells: the orientation is unknown (an operator-classified launch), all four NaN
        optional["final_orientation"] = tuple(field(c, _parse_float, math.nan, True) for c in ORIENTATION_COLUMNS)
    if reasons:
        raise ValueError("; ".join(reasons))
    if optional["run_id"] is None:
        raise ValueError("run_id is empty and no run id was given for the file")
    condition = LaunchCondition(**condition_values)
    condition.validate()
    trial_id = field("trial_id", non_empty, None) or trial_id_for(condition)
    if reasons:
        raise ValueError("; ".join(reasons))
    outcome = LaunchOutcome(trial_id=trial_id, condition=condition, upright=upright, **optional)
    outcome.validate()
    return outcome


def _check_header(header, run_id):
    problems = []
    names = [name.strip() for name in header]
    for name in sorted({n for n in names if names.count(n) > 1}):
        problems.append(f"column {name!r} appears more than once")
    for name in names:
        if name not in REQUIRED_COLUMNS + OPTIONAL_COLUMNS:
            problems.append(f"unknown column {name!r} (allowed: {', '.join(REQUIRED_COLUMNS + OPTIONAL_COLUMNS)})")
    missing = [name for name in REQUIRED_COLUMNS if name not in names]
    if missing:
        problems.append(f"missing required column(s) {', '.join(missing)}")
    orientation = [name for name in ORIENTATION_COLUMNS if name in names]
    if orientation and len(orientation) != len(ORIENTATION_COLUMNS):
        problems.append(f"orientation needs all of {', '.join(ORIENTATION_COLUMNS)} or none")
    if "run_id" not in names and not run_id:
        problems.append("no run_id column: give the run id for the whole file")
    return names, problems


def read_outcome_csv(path: typing.Union[str, os.PathLike],
                     run_id: typing.Optional[str] = None) -> typing.List[LaunchOutcome]:
    """Read a CSV of launch outcomes (schema: ``docs/outcome-csv.md``); all rows or none.

    Parameters
    ----------
    path : str or os.PathLike
    run_id : str, optional
        Run id for rows without one (a file without a ``run_id`` column, or an empty cell).

    Returns
    -------
    list of LaunchOutcome
        In file order.

    Raises
    ------
    OutcomeCsvError
        Listing every bad row with its line number (the header is line 1) and reason.
    """
    problems = []
    outcomes = []
    first_line_of: typing.Dict[typing.Tuple[str, str], int] = {}
    try:
        stream = open(path, newline="", encoding="utf-8-sig")
    except OSError as exc:
        raise OutcomeCsvError(path, [(0, f"cannot read: {exc.strerror}")]) from exc
    with stream:
        # strict: a quote left open is an error, not a field that swallows every following line
        reader = csv.reader(stream, strict=True)
        end_of_previous = 0
        try:
            header = next(reader, None)
            if header is None:
                raise OutcomeCsvError(path, [(1, "empty file: no header line")])
            names, header_problems = _check_header(header, run_id)
            if header_problems:
                raise OutcomeCsvError(path, [(1, reason) for reason in header_problems])
            end_of_previous = reader.line_num
            for row in reader:
                line = end_of_previous + 1
                end_of_previous = reader.line_num
                if not row or all(not cell.strip() for cell in row):
                    continue  # a blank line holds no outcome
                if len(row) != len(names):
                    problems.append((line, f"expected {len(names)} fields, got {len(row)}"))
                    continue
                try:
                    outcome = _parse_row(dict(zip(names, row)), run_id)
                except ValueError as exc:
                    problems.append((line, str(exc)))
                    continue
                key = (outcome.run_id, outcome.trial_id)
                if key in first_line_of:
                    problems.append((line, f"trial {outcome.trial_id} of run {outcome.run_id} already on line "
                                           f"{first_line_of[key]}"))
                    continue
                first_line_of[key] = line
                outcomes.append(outcome)
        except csv.Error as exc:
            line = end_of_previous + 1
            if "unexpected end of data" in str(exc):
                problems.append((line, f"unterminated quote: the quoted field opened in the row starting on line "
                                       f"{line} is never closed (it runs to line {reader.line_num}, the end of "
                                       f"the file)"))
            else:
                problems.append((line, f"unreadable CSV: {exc}"))
        except UnicodeDecodeError as exc:
            problems.append((reader.line_num + 1, f"not UTF-8 text: {exc.reason}"))
    if problems:
        raise OutcomeCsvError(path, problems)
    return outcomes


def _format_float(value):
    return "" if math.isnan(value) else repr(float(value))


def write_outcome_csv(path: typing.Union[str, os.PathLike], outcomes: typing.Iterable[LaunchOutcome]) -> None:
    """Write launch outcomes with every column of ``EXPORT_COLUMNS`` (NaN as an empty cell)."""
    with open(path, "w", newline="", encoding="utf-8") as stream:
        writer = csv.writer(stream)
        writer.writerow(EXPORT_COLUMNS)
        for outcome in outcomes:
            condition = outcome.condition
            writer.writerow([
                outcome.run_id, outcome.trial_id, condition.configuration, repr(float(condition.height_m)),
                repr(float(condition.speed_mps)), repr(float(condition.angle_deg)), condition.repetition,
                str(outcome.upright).lower(), outcome.backend, _format_float(outcome.travel_time_s),
                _format_float(outcome.measured_speed_mps), str(outcome.speed_out_of_tolerance).lower(),
                outcome.classified_by, outcome.note, repr(float(outcome.stamp_s)),
                *(_format_float(q) for q in outcome.final_orientation),   # unknown: empty cells
                "" if outcome.seed == NO_SEED else outcome.seed,
                *(_format_float(value) for value in outcome.continuous().values())])   # not measured: empty
