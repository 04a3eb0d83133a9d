"""The daemon's JSON as pandas DataFrames: units in the column names, errors beside their values.

Pure functions of the JSON the daemon sent (and of its API description for the units): no I/O.
A number's unit comes from where the daemon states it -- `x-unit` in the API description for
points, result rows and aggregates, a fit's own `units`, a claim figure's `unit` -- and is written
into its column's name, "Uz [m/s]". The client keeps no list of fields or units of its own: a field
the daemon adds appears as a column (without a unit until the description gives it one).
"""

from __future__ import annotations

from typing import Any, Iterable, Mapping, Optional, Sequence

import pandas as pd

# What the description's schemas are called (schema/openapi.json components.schemas).
POINT_SCHEMA = "Point"
RESULT_SCHEMA = "ResultRow"
AGGREGATE_SCHEMA = "PointAggregate"
RUN_DETAIL_SCHEMA = "RunDetail"


def column_name(field: str, unit: Optional[str]) -> str:
    """ "Uz", "m/s" -> "Uz [m/s]"; a field without a unit keeps its name."""
    return f"{field} [{unit}]" if unit else field


class Schemas:
    """The API description's schemas, read for two things: field order and units (x-unit)."""

    def __init__(self, openapi: Mapping[str, Any]) -> None:
        self._schemas = openapi.get("components", {}).get("schemas", {})

    def fields(self, schema: str) -> list[str]:
        """The schema's properties in the order the description lists them."""
        return list(self._schemas.get(schema, {}).get("properties", {}).keys())

    def units(self, *schemas: str) -> dict[str, str]:
        """Field -> unit over `schemas` (the first one that states a field's unit wins)."""
        found: dict[str, str] = {}
        for schema in schemas:
            for field, prop in self._schemas.get(schema, {}).get("properties", {}).items():
                unit = prop.get("x-unit") if isinstance(prop, Mapping) else None
                if unit and field not in found:
                    found[field] = unit
        return found

    def nested_units(self, schema: str, field: str) -> dict[str, str]:
        """Units of the properties of `schema`'s object property `field` (inline, or in allOf)."""
        node = self._schemas.get(schema, {})
        for part in [node] + list(node.get("allOf", [])):
            prop = part.get("properties", {}).get(field)
            if isinstance(prop, Mapping):
                return {k: v["x-unit"] for k, v in prop.get("properties", {}).items() if "x-unit" in v}
        return {}


def _ordered(keys: Iterable[str], order: Sequence[str]) -> list[str]:
    """`keys` with those in `order` first, in that order, then the rest as they came."""
    keys = list(dict.fromkeys(keys))
    first = [k for k in order if k in keys]
    return first + [k for k in keys if k not in set(first)]


def _frame(rows: list[dict[str, Any]], order: Sequence[str], units: Mapping[str, str]) -> pd.DataFrame:
    keys: list[str] = []
    for row in rows:
        keys.extend(k for k in row if k not in keys)
    columns = _ordered(keys, order)
    frame = pd.DataFrame.from_records(rows, columns=columns)
    return frame.rename(columns={c: column_name(c, units.get(c)) for c in columns})


def results_frame(rows: list[dict[str, Any]], schemas: Schemas) -> pd.DataFrame:
    """One row per run: its point, U_z with its standard error and 95 % half-width beside it, and
    every other column of the results table, in the table's order (ResultRow), units in the names.
    A campaign run's `sweeps` (a list) stays one cell."""
    return _frame(rows, schemas.fields(RESULT_SCHEMA), schemas.units(RESULT_SCHEMA, POINT_SCHEMA))


def aggregates_frame(aggregates: list[dict[str, Any]], schemas: Schemas) -> pd.DataFrame:
    """One row per point over its replicate beds: the point, K and n, the mean U_z with its
    standard error, 95 % half-width and between-bed sd beside it. Each bed's own value is in the
    results frame (the aggregate's `values` are left out here: one row per bed is the results)."""
    rows = [{k: v for k, v in a.items() if k != "values"} for a in aggregates]
    order = schemas.fields(POINT_SCHEMA) + [f for f in schemas.fields(AGGREGATE_SCHEMA) if f != "mode"]
    return _frame(rows, order, schemas.units(AGGREGATE_SCHEMA, POINT_SCHEMA))


def _fit_unit(key: str, units: Mapping[str, str]) -> Optional[str]:
    # A parameter's error and range share its unit: C1_stderr and C1, A_from and A.
    if key in units:
        return units[key]
    for suffix in ("_stderr", "_from", "_to"):
        if key.endswith(suffix) and key[: -len(suffix)] in units:
            return units[key[: -len(suffix)]]
    return None


def fits_frame(fits: Mapping[str, Any]) -> pd.DataFrame:
    """One row per branch (rising, sinking) of a sweep's fit (GET /sweeps/{id}/fits): the law,
    each parameter with its standard error beside it (units from the fit's own `units`), n and
    R^2. No branch (nothing to fit) gives an empty frame; `fits.reason` says why."""
    rows = []
    for branch in fits.get("branches", []):
        row: dict[str, Any] = {"sweep_id": fits.get("sweep_id"), "param": fits.get("param"),
                               "kind": fits.get("kind")}
        fit: Mapping[str, Any] = {}
        for key, value in branch.items():
            if isinstance(value, Mapping):
                fit = value
            else:
                row[key] = value
        units = fit.get("units", {})
        for key, value in fit.items():
            if key != "units":
                row[column_name(key, _fit_unit(key, units))] = value
        rows.append(row)
    frame = pd.DataFrame.from_records(rows)
    frame.attrs["reason"] = fits.get("reason", "")
    frame.attrs["left_out"] = fits.get("left_out", [])
    return frame


def _flat(d: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """`d` in one level: nested objects as "rule.kind", lists of plain values kept as one cell,
    lists of objects (parts, figures, missing points) left to frames of their own."""
    flat: dict[str, Any] = {}
    for key, value in d.items():
        name = prefix + key
        if isinstance(value, Mapping):
            flat.update(_flat(value, name + "."))
        elif isinstance(value, list) and any(isinstance(v, (Mapping, list)) for v in value):
            continue
        else:
            flat[name] = value
    return flat


def claims_frame(claims: Mapping[str, Any]) -> pd.DataFrame:
    """One row per claim (F1 ...) of a campaign run: its verdict at the run's scale, the reason,
    how many parts decided it and how many points were missing, and every other field the daemon
    gives, nested ones as "paper.text", "rule.kind" (a verdict's error rate among them when the
    daemon states one)."""
    rows = []
    for claim in claims.get("claims", []):
        row = _flat(claim)
        row["parts"] = len(claim.get("parts", []))
        row["missing"] = len(claim.get("missing", []))
        rows.append(row)
    return pd.DataFrame.from_records(rows)


def claim_parts_frame(claims: Mapping[str, Any]) -> pd.DataFrame:
    """One row per part of each claim: the claim's id, the part's name, verdict and reason."""
    rows = []
    for claim in claims.get("claims", []):
        for part in claim.get("parts", []):
            rows.append({"claim": claim.get("id"), **_flat(part)})
    return pd.DataFrame.from_records(rows)


def claim_figures_frame(claims: Mapping[str, Any]) -> pd.DataFrame:
    """One row per figure a part rests on: its value, standard error and 95 % interval [lo, hi]
    (or, censored, the bound), with its unit in a column of its own (figures of one part may
    differ in unit), and the verdict the figure gives."""
    rows = []
    for claim in claims.get("claims", []):
        for part in claim.get("parts", []):
            for figure in part.get("figures", []):
                rows.append({"claim": claim.get("id"), "part": part.get("name"), **_flat(figure)})
    order = ["claim", "part", "name", "value", "stderr", "lo", "hi", "unit", "censored", "bound", "text", "verdict"]
    frame = pd.DataFrame.from_records(rows)
    return frame[_ordered(frame.columns, order)] if rows else frame


def trajectory_frame(trajectory: Mapping[str, Any], schemas: Schemas) -> pd.DataFrame:
    """The SO's path in a run (GET /runs/{id} trajectory): t, x, y, z, units in the names."""
    units = schemas.nested_units(RUN_DETAIL_SCHEMA, "trajectory")
    columns = {column_name(k, units.get(k)): v for k, v in trajectory.items() if isinstance(v, list)}
    return pd.DataFrame(columns)


def table_frame(rows: list[dict[str, Any]]) -> pd.DataFrame:
    """A plain listing (sweeps, runs, beds): one row per item, nested objects flattened with '.'."""
    return pd.json_normalize(rows) if rows else pd.DataFrame()
