"""MuJoCo's own C functions, callable from numba kernels.

The compiled collision filter (:mod:`envs.models.filter`) decides most samples of a path
from geometric bounds, and hands every other sample to the exact check the Python backends
make: ``mj_kinematics`` then ``mj_collision`` on the checker's ``MjData``, and a look at
``d->ncon``. Calling them from inside the kernel (instead of returning to Python per
sample) is what makes that hand-over cheap. Three pieces:

- the addresses of ``mj_kinematics`` and ``mj_collision`` in the ``libmujoco`` that the
  ``mujoco`` package ships (the same library its bindings use: ``dlopen`` returns the
  loaded copy);
- :func:`call_model_data`, a numba intrinsic that calls ``void f(const mjModel*, mjData*)``
  through an address passed at run time: no address is baked into the compiled code, so
  numba's on-disk cache stays valid across processes;
- :func:`ncon_view`, a one-element ``int32`` array aliasing ``d->ncon``, at the offset
  computed from MuJoCo's own struct description (``mujoco.introspect``) and verified
  against the bindings' ``data.ncon`` before use;
- :func:`store_float64` and :func:`load_int32`, a store and a load at an address passed at
  run time, so that one kernel call can write the qpos and read the ncon of several
  ``MjData`` (a vector env's scenes): :func:`exact_addresses` lists what a kernel needs.
"""

from __future__ import annotations

import ctypes
import functools
import glob
import os
from typing import Any, TypeAlias

import mujoco
import numpy as np
from llvmlite import ir  # type: ignore[import-untyped]  # llvmlite ships no type information
from mujoco.introspect import ast_nodes, structs
from numba import types
from numba.extending import intrinsic


@functools.cache
def _library() -> ctypes.CDLL:
    folder = os.path.dirname(mujoco.__file__)
    candidates = sorted(
        glob.glob(os.path.join(folder, "libmujoco.so*"))
        + glob.glob(os.path.join(folder, "libmujoco*.dylib"))
        + glob.glob(os.path.join(folder, "mujoco.dll"))
    )
    if not candidates:
        raise RuntimeError(f"no libmujoco found beside the mujoco package in {folder}")
    return ctypes.CDLL(candidates[0])


@functools.cache
def function_address(name: str) -> int:
    """Address of the exported MuJoCo C function ``name`` (e.g. ``"mj_collision"``)."""
    address = ctypes.cast(getattr(_library(), name), ctypes.c_void_p).value
    if address is None:  # a NULL symbol: getattr raises for a missing one, so not expected
        raise RuntimeError(f"libmujoco exports {name} at address NULL")
    return int(address)


@intrinsic
def call_model_data(typingctx, function, model, data):
    """``function(model, data)`` for a ``void (const mjModel*, mjData*)`` C function; all
    three arguments are addresses (``uintp``)."""
    signature = types.void(types.uintp, types.uintp, types.uintp)

    def codegen(context, builder, sig, args):
        pointer = ir.IntType(8).as_pointer()
        function_type = ir.FunctionType(ir.VoidType(), [pointer, pointer])
        callee = builder.inttoptr(args[0], function_type.as_pointer())
        builder.call(callee, [builder.inttoptr(args[1], pointer),
                              builder.inttoptr(args[2], pointer)])
        return context.get_dummy_value()

    return signature, codegen


@intrinsic
def call_status(typingctx, function, argument):
    """``function(argument)`` for an ``int64_t (void*)`` C function, its result; both
    arguments are addresses (``uintp``)."""
    signature = types.int64(types.uintp, types.uintp)

    def codegen(context, builder, sig, args):
        pointer = ir.IntType(8).as_pointer()
        function_type = ir.FunctionType(ir.IntType(64), [pointer])
        callee = builder.inttoptr(args[0], function_type.as_pointer())
        return builder.call(callee, [builder.inttoptr(args[1], pointer)])

    return signature, codegen


@intrinsic
def store_float64(typingctx, address, index, value):
    """``((double*) address)[index] = value``; ``address`` an address (``uintp``)."""
    signature = types.void(types.uintp, types.intp, types.float64)

    def codegen(context, builder, sig, args):
        pointer = builder.inttoptr(args[0], ir.DoubleType().as_pointer())
        builder.store(args[2], builder.gep(pointer, [args[1]]))
        return context.get_dummy_value()

    return signature, codegen


@intrinsic
def load_int32(typingctx, address):
    """``*(int*) address``; ``address`` an address (``uintp``)."""
    signature = types.int32(types.uintp)

    def codegen(context, builder, sig, args):
        return builder.load(builder.inttoptr(args[0], ir.IntType(32).as_pointer()))

    return signature, codegen


def exact_addresses(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """(6,) ``uint64``: where a kernel writes ``data``'s qpos and reads its ncon (checked
    by :func:`ncon_view`), ``mj_kinematics``, ``mj_collision``, the model and the data
    (both must outlive every kernel call given these)."""
    ncon_view(data)  # verifies the offset on this data
    return np.array([data.qpos.ctypes.data, data._address + ncon_offset(),
                     function_address("mj_kinematics"), function_address("mj_collision"),
                     model._address, data._address], dtype=np.uint64)


#: A ctypes type of one of mjData's fields: a scalar, a fixed array or a plain struct.
_CType: TypeAlias = (
    "type[ctypes._SimpleCData[Any]] | type[ctypes.Array[Any]] | type[ctypes.Structure]"
)

_SCALARS: dict[str, _CType] = {
    "int": ctypes.c_int,
    "mjtNum": ctypes.c_double,
    "float": ctypes.c_float,
    "mjtSize": ctypes.c_uint64,
    "size_t": ctypes.c_size_t,
    "uintptr_t": ctypes.c_size_t,
    "mjtBool": ctypes.c_ubyte,
    "mjtByte": ctypes.c_ubyte,
}


def _ctype(node: Any) -> _CType:
    if isinstance(node, ast_nodes.ArrayType):
        return _ctype(node.inner_type) * int(np.prod(node.extents))
    if isinstance(node, ast_nodes.PointerType):
        return ctypes.c_void_p
    name = node.name
    if name in _SCALARS:
        return _SCALARS[name]
    if name in structs.STRUCTS:
        return _struct(name)
    raise RuntimeError(f"mujoco.introspect type {name!r} has no ctypes equivalent here")


@functools.cache
def _struct(name: str) -> type[ctypes.Structure]:
    fields = [(field.name, _ctype(field.type)) for field in structs.STRUCTS[name].fields]
    return type(name, (ctypes.Structure,), {"_fields_": fields})


@functools.cache
def ncon_offset() -> int:
    """Byte offset of ``ncon`` in ``mjData``: the struct's fields before it, laid out by
    ctypes with C's alignment rules (they are scalars, fixed arrays and plain structs)."""
    fields = []
    for field in structs.STRUCTS["mjData"].fields:
        fields.append((field.name, _ctype(field.type)))
        if field.name == "ncon":
            break
    else:
        raise RuntimeError("mujoco.introspect describes no mjData.ncon")
    # Any: a struct whose fields (attribute ncon) exist at run time only.
    prefix: Any = type("mjDataPrefix", (ctypes.Structure,), {"_fields_": fields})
    return int(prefix.ncon.offset)


def ncon_view(data: mujoco.MjData) -> np.ndarray:
    """A (1,) ``int32`` array that aliases ``data``'s ``ncon`` (``data`` must outlive it).

    Checked on the spot: the value read through it must follow ``data.ncon`` as the
    bindings report it while it is set to several different values.
    """
    cell = (ctypes.c_int * 1).from_address(data._address + ncon_offset())
    view = np.ctypeslib.as_array(cell)
    saved = data.ncon
    try:
        for value in (7, 0, 3):
            cell[0] = value
            if data.ncon != value:
                raise RuntimeError(
                    "mjData.ncon is not where mujoco.introspect puts it; the compiled "
                    "collision backend cannot run with this MuJoCo build"
                )
    finally:
        cell[0] = saved
    return view
