"""The zarr store of a parameter study: written block by block, resumable, refused when foreign.

Layout (zarr format 3, readable with ``xarray.open_zarr(path)``): one array per coordinate and per
variable of the study's dataset, with its dimension names; every variable is chunked by the
study's blocks, so each block owns its chunks and is written whole (zarr writes each chunk file
atomically). After a block's chunks, its completion record goes into the group
``fakeack_blocks``: array ``done`` holds, per block, a 64-bit hash of the block's data (0: not
complete), one chunk per block. A killed run leaves complete blocks with matching records and
at most some chunks of unfinished blocks, which a resumed run writes again.

The root's attributes identify the study (``fakeack_study``: a SHA-256 of the systems, the grid and
the settings; ``fakeack_version``; ``fakeack_tile``). Resuming a store refuses, with a message
that says why: a path that is not a fakeack study store, a store of another study or version, and
a store whose data does not match its completion records (truncated or damaged).
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np

from .spec import Layout

__all__ = [
    "StoreError",
    "Variable",
    "GridStore",
]


_BLOCKS = "fakeack_blocks"


class StoreError(ValueError):
    """A store that cannot be used: foreign, of another study, or truncated."""


@dataclass(frozen=True)
class Variable:
    """One array of the study: its dimensions, kind ("f" float64, "i" int64, "U" text) and attrs."""

    name: str
    dims: tuple[str, ...]
    kind: str
    attrs: Mapping[str, Any]
    extent: tuple[int, ...] = ()
    """Sizes of the dimensions after (system, lam, ratio), e.g. (n_beta,)."""

    @property
    def fill(self) -> Any:
        """Value of an unwritten cell."""
        return {"f": np.nan, "i": 0, "U": ""}[self.kind]

    @property
    def dtype(self) -> Any:
        """The zarr data type."""
        return {"f": "float64", "i": "int64", "U": str}[self.kind]


def block_hash(data: Mapping[str, np.ndarray]) -> int:
    """A nonzero 64-bit hash of one block's arrays (names, shapes and values, text as UTF-8)."""
    h = hashlib.blake2b(digest_size=8)
    for name in sorted(data):
        arr = np.asarray(data[name])
        h.update(f"{name}{arr.shape}".encode())
        if arr.dtype.kind in "fiu":
            h.update(np.ascontiguousarray(arr, dtype=arr.dtype.newbyteorder("<")).tobytes())
        else:
            h.update("\x00".join(str(x) for x in arr.ravel()).encode())
    return int.from_bytes(h.digest(), "little") or 1


class GridStore:
    """A study's zarr store (see the module's description)."""

    def __init__(self, group: Any, layout: Layout, variables: list[Variable], path: Path):
        self.group, self.layout, self.variables, self.path = group, layout, variables, path

    # -- creating and opening ------------------------------------------------------------------

    @classmethod
    def create(
        cls,
        path: Path,
        layout: Layout,
        variables: list[Variable],
        coords: Mapping[str, tuple[tuple[str, ...], np.ndarray, Mapping[str, Any]]],
        attrs: Mapping[str, Any],
    ) -> GridStore:
        """A new store at ``path`` (which must not exist) with every array and no data."""
        import zarr

        group = zarr.open_group(str(path), mode="w-", zarr_format=3)
        for name, (dims, values, vattrs) in coords.items():
            kind = "U" if values.dtype.kind in "UO" else "f"
            arr = group.create_array(
                name,
                shape=values.shape,
                dtype=str if kind == "U" else values.dtype,
                chunks=values.shape,
                dimension_names=list(dims),
                attributes=dict(vattrs),
            )
            arr[...] = values.astype(object) if kind == "U" else values
        index_coords = {name for name, (dims, _, _) in coords.items() if dims == (name,)}
        extra = {name: dims for name, (dims, _, _) in coords.items() if name not in index_coords}
        for var in variables:
            vattrs = dict(var.attrs)
            listed = [c for c, dims in extra.items() if set(dims) <= set(var.dims)]
            if listed:
                vattrs["coordinates"] = " ".join(listed)
            group.create_array(
                var.name,
                shape=cls._shape(layout, var),
                dtype=var.dtype,
                chunks=cls._chunks(layout, var),
                fill_value=var.fill,
                dimension_names=list(var.dims),
                attributes=vattrs,
            )
        blocks = group.create_group(_BLOCKS)
        blocks.create_array("done", shape=(layout.n_blocks,), dtype="uint64", chunks=(1,), fill_value=0)
        group.attrs.update(dict(attrs))
        return cls(group, layout, variables, path)

    @classmethod
    def open(
        cls, path: Path, layout: Layout | None, variables: list[Variable], study: str, version: str
    ) -> GridStore:
        """An existing store of this very study, after checking that it is one."""
        import zarr

        try:
            group = zarr.open_group(str(path), mode="r+")
            attrs = dict(group.attrs)
        except Exception as exc:  # noqa: BLE001 - whatever zarr raises for a non-store
            raise StoreError(f"store {str(path)!r} is not a zarr store of a fakeack study ({exc})") from None
        if "fakeack_study" not in attrs:
            raise StoreError(
                f"store {str(path)!r} is not a fakeack study store (no fakeack_study attribute); "
                "refusing to write into it"
            )
        if attrs.get("fakeack_version") != version:
            raise StoreError(
                f"store {str(path)!r} was written by fakeack {attrs.get('fakeack_version')}, this is "
                f"fakeack {version}: results could differ, so it is not resumed; use a new store"
            )
        if attrs["fakeack_study"] != study:
            raise StoreError(
                f"store {str(path)!r} holds another study (its systems, grid or settings differ); "
                "refusing to merge; use a new store, or the arguments the store was made with"
            )
        tile = tuple(cast("Sequence[int]", attrs.get("fakeack_tile", ())))  # written by this module
        if layout is not None and tuple(layout.tile) != tile:
            raise StoreError(
                f"store {str(path)!r} is tiled in blocks of {' x '.join(map(str, tile))} cells; "
                "resume it with block=None (or the block it was made with)"
            )
        store = cls(group, Layout(tuple(attrs["fakeack_shape"]), tile), variables, path)  # type: ignore[arg-type]
        store._check_arrays()
        return store

    def _check_arrays(self) -> None:
        for var in self.variables:
            try:
                arr = self.group[var.name]
            except KeyError:
                raise StoreError(
                    f"store {str(self.path)!r} is truncated: array {var.name!r} is missing"
                ) from None
            if tuple(arr.shape) != self._shape(self.layout, var):
                raise StoreError(
                    f"store {str(self.path)!r} is damaged: array {var.name!r} has shape {arr.shape}"
                )
        try:
            done = self.group[_BLOCKS]["done"]
        except KeyError:
            raise StoreError(
                f"store {str(self.path)!r} is truncated: its block records ({_BLOCKS}/done) are missing"
            ) from None
        if done.shape != (self.layout.n_blocks,):
            raise StoreError(f"store {str(self.path)!r} is damaged: {done.shape[0]} block records")

    @staticmethod
    def _shape(layout: Layout, var: Variable) -> tuple[int, ...]:
        return (*layout.shape, *var.extent)

    @staticmethod
    def _chunks(layout: Layout, var: Variable) -> tuple[int, ...]:
        return (1, *layout.tile, *var.extent)

    # -- blocks --------------------------------------------------------------------------------

    def records(self) -> np.ndarray:
        """Each block's completion record (0: not complete)."""
        try:
            return np.asarray(self.group[_BLOCKS]["done"][...], dtype=np.uint64)
        except Exception as exc:  # noqa: BLE001 - a damaged record chunk
            raise StoreError(
                f"store {str(self.path)!r} is damaged: cannot read its block records ({exc})"
            ) from None

    def read_block(self, index: int) -> dict[str, np.ndarray]:
        """The arrays of one block as stored."""
        region = self.layout.region(index)
        return {var.name: _plain(self.group[var.name][region]) for var in self.variables}

    def verify(self) -> set[int]:
        """The complete blocks, after checking each one's data against its record."""
        done = self.records()
        complete = set()
        for index in np.flatnonzero(done):
            try:
                data = self.read_block(int(index))
            except Exception as exc:  # noqa: BLE001 - a truncated or unreadable chunk
                raise StoreError(
                    f"store {str(self.path)!r} is truncated or damaged: block {index} is recorded as "
                    f"complete but its data cannot be read ({exc}); delete it and start again"
                ) from None
            if block_hash(data) != int(done[index]):
                raise StoreError(
                    f"store {str(self.path)!r} is truncated or damaged: block {index}'s data does not "
                    "match its completion record; delete it and start again"
                )
            complete.add(int(index))
        return complete

    def write_block(self, index: int, data: Mapping[str, np.ndarray]) -> None:
        """Write one block's chunks, then its completion record."""
        region = self.layout.region(index)
        for var in self.variables:
            values = data[var.name]
            self.group[var.name][region] = values.astype(object) if var.kind == "U" else values
        self.group[_BLOCKS]["done"][index] = np.uint64(
            block_hash({v.name: data[v.name] for v in self.variables})
        )

    def read_all(self) -> dict[str, np.ndarray]:
        """Every variable, whole."""
        return {var.name: _plain(self.group[var.name][...]) for var in self.variables}

    def finish(self, attrs: Mapping[str, Any]) -> None:
        """Record the finished run's attributes (the root's metadata is rewritten atomically)."""
        self.group.attrs.update(dict(attrs))


def _plain(arr: Any) -> np.ndarray:
    """Text as a fixed-width numpy str array, numbers as they are."""
    a = np.asarray(arr)
    if a.dtype.kind not in "fiub":
        return np.array(a.astype(object).tolist(), dtype=str).reshape(a.shape)
    return a
