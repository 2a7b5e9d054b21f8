"""One rosbags reader for every bag the package opens, with its type stores shared.

rosbags' ``AnyReader`` builds a new type store from a bag's message definitions every time
it opens a bag (it parses each definition, generates and runs the types' Python code,
checks their hashes), and then generates each type's deserialiser code again on first use
in that store: some 0.15 s CPU per opening before the first message, paid again by every
reader of the same bag (``augment`` opens its input three to five times) and of every bag
recorded with the same definitions. :func:`bag_reader` gives the same reader with the type
store of a bag's definitions built once per process and reused (least recently used of
:data:`STORES_KEPT` sets of definitions), its deserialisers with it. A store is only read
(messages deserialised, definitions looked up); what ``AnyReader`` checks and refuses is
checked and refused the same (the hashes, a bag without definitions and no default store).
"""

from __future__ import annotations

import functools
import os
import threading
from collections import OrderedDict
from collections.abc import Callable, Sequence
from importlib.metadata import version
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys.store import Typestore

__all__ = ["STORES_KEPT", "bag_reader"]

#: Sets of message definitions whose type stores are kept (least recently used dropped).
STORES_KEPT = 16

_STORES: OrderedDict[tuple, Typestore] = OrderedDict()
_LOCK = threading.Lock()  # the live view reads bags from threads


def _build_store(is2: bool, connections: Sequence) -> Typestore:
    """rosbags' ``AnyReader._open`` type store of bags with these definitions (0.11.9)."""
    # lazy: rosbags' type system adds 0.07 s CPU to `import are_stats.logs`
    from rosbags.highlevel import AnyReaderError
    from rosbags.interfaces import MessageDefinitionFormat
    from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

    typs: dict = {}
    digests: dict[str, str] = {}
    for connection in connections:
        if connection.msgdef.format == MessageDefinitionFormat.MSG:
            typs.update(get_types_from_msg(connection.msgdef.data, connection.msgtype))
        else:
            sep = "=" * 80 + "\n"
            if connection.msgdef.data.startswith(f"{sep}IDL: "):
                for msgdef in connection.msgdef.data.split(sep)[1:]:
                    hdr, idl = msgdef.split("\n", 1)
                    if not hdr.startswith("IDL: "):  # rosbags asserts it
                        raise AssertionError(f"IDL of {connection.msgtype}: header {hdr!r}")
                    typs.update(get_types_from_idl(idl))
            else:
                typs.update(get_types_from_idl(connection.msgdef.data))
        if connection.digest:
            digests[connection.msgtype] = connection.digest
    typestore = get_typestore(Stores.EMPTY)
    typestore.register(typs)
    for msgtype, digest in digests.items():
        have = typestore.hash_rihs01(msgtype) if is2 else typestore.generate_msgdef(msgtype)[1]
        if have != digest:
            raise AnyReaderError(f"Message type {msgtype!r} hash mismatch {have} != {digest}")
    return typestore


#: The rosbags releases whose ``AnyReader._open`` the shared-store reader replaces (it
#: rewrites that private method); with any other release :func:`bag_reader` is rosbags'
#: own ``AnyReader``, slower to open and otherwise the same.
TESTED_ROSBAGS = ("0.11.",)


@functools.cache
def _rosbags_version() -> str:
    return version("rosbags")


def _shared_stores_supported() -> bool:
    """Whether the installed rosbags is one whose ``AnyReader._open`` was rewritten here."""
    return _rosbags_version().startswith(TESTED_ROSBAGS)


@functools.cache
def _reader_class() -> type[AnyReader]:
    # lazy: rosbags' reader adds 0.35 s CPU to `import are_stats.logs`
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.interfaces import MessageDefinitionFormat
    from rosbags.typesys import Stores, get_typestore

    class SharedTypesReader(AnyReader):
        """``AnyReader`` whose type store is the shared one of its bag's definitions."""

        def _open(self) -> None:
            for reader in self.readers:
                self.stack.enter_context(reader)
            connections = [c for r in self.readers for c in r.connections]
            defined = [c for c in connections if c.msgdef.format != MessageDefinitionFormat.NONE]
            if connections and not defined:  # rosbags' own path: the default store's types
                default = self.default_typestore
                if callable(default):  # made only for such a bag
                    default = default()
                if default is None:
                    raise AnyReaderError(
                        "Bag contains no type definitions. "
                        "Instantiate AnyReader with a default_typestore argument."
                    )
                store = get_typestore(Stores.EMPTY)
                store.register(default.fielddefs)
            else:
                key = (
                    self.is2,
                    tuple(
                        (c.msgtype, c.msgdef.format.name, c.msgdef.data, c.digest) for c in defined
                    ),
                )
                with _LOCK:
                    store = _STORES.get(key)
                    if store is not None:
                        _STORES.move_to_end(key)
                if store is None:
                    store = _build_store(self.is2, defined)
                    with _LOCK:
                        _STORES[key] = store
                        while len(_STORES) > STORES_KEPT:
                            _STORES.popitem(last=False)
            self.connections = connections
            self.typestore = store

    return SharedTypesReader


def bag_reader(
    paths: str | os.PathLike | Sequence[str | os.PathLike],
    default_typestore: Typestore | Callable[[], Typestore] | None = None,
) -> AnyReader:
    """A rosbags ``AnyReader`` of ``paths`` (one bag, or rosbags' list of paths) whose
    type store is shared with every reader of the same message definitions (module
    docstring): the same connections, messages and errors, without rebuilding the store.

    Parameters
    ----------
    paths : path or sequence of paths
    default_typestore : Typestore or callable, optional
        The types of a bag that carries no definitions (as ``AnyReader``'s), or a function
        returning them, called only when the bag is such a one (building a store costs
        some 0.03 s CPU, paid for nothing by a bag that carries its definitions).

    Returns
    -------
    rosbags.highlevel.AnyReader
        Not open: use it as a context manager.
    """
    if isinstance(paths, str | os.PathLike):
        paths = [paths]
    paths = [Path(p) for p in paths]
    if not _shared_stores_supported():
        from rosbags.highlevel import AnyReader  # lazy: rosbags' reader adds 0.35 s CPU

        if callable(default_typestore):
            default_typestore = default_typestore()
        return AnyReader(paths, default_typestore=default_typestore)
    return _reader_class()(paths, default_typestore=default_typestore)
