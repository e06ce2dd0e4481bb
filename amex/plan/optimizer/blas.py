"""numpy's own BLAS and SciPy's LAPACK, called from compiled code: the same routines, the same bits.

A dot product or a small matrix product that numpy hands to OpenBLAS sums in OpenBLAS's order,
which depends on the CPU kernel OpenBLAS picked (docs/reliability.md). Compiled code that must
give numpy's numbers therefore calls the very routines numpy calls, with the arguments numpy
passes them (``numpy/_core/src/common/cblasfuncs.c`` for ``dot``, ``umath/matmul.c.src`` for
``@``): ``cblas_ddot``, ``cblas_dgemv`` and ``cblas_dsyrk`` of numpy's bundled OpenBLAS, and
LAPACK's ``dpbsv`` of SciPy's (what ``scipy.linalg.lapack.dpbsv`` calls). Each is bound by name
(``llvmlite.binding.add_symbol``) when this module is imported, so the kernels that call them
stay in Numba's on-disk cache: the cached code names the symbol, not an address.

:data:`BOUND` is False where numpy was built against another BLAS (no ``scipy_cblas_*64_``
symbols in its bundled library): the callers then keep their numpy path.
"""

from __future__ import annotations

import ctypes
import glob
import os
from typing import Any

import llvmlite.binding as llvm
import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import get_cython_function_address, intrinsic

__all__ = ["BOUND", "ddot", "dpbsv", "dot_rows", "gram_upper", "transposed_dot"]

_ROW_MAJOR, _COL_MAJOR, _NO_TRANS, _TRANS, _UPPER = 101, 102, 111, 112, 121
_PREFIX = "amex_blas_"  # the names the compiled code calls (bound below)
_CBLAS = ("ddot", "dgemv", "dsyrk")


def _numpy_openblas() -> ctypes.CDLL | None:
    """The OpenBLAS bundled with numpy (ILP64, symbols ``scipy_cblas_*64_``), or None."""
    libs = os.path.join(os.path.dirname(np.__file__), os.pardir, "numpy.libs")
    for path in sorted(glob.glob(os.path.join(libs, "libscipy_openblas64_*.so*"))):
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        if all(hasattr(lib, f"scipy_cblas_{name}64_") for name in _CBLAS):
            return lib
    return None


def _bind() -> bool:
    """Register the routines' addresses under :data:`_PREFIX` names; whether all were found."""
    lib = _numpy_openblas()
    if lib is None:
        return False
    for name in _CBLAS:
        address = ctypes.cast(getattr(lib, f"scipy_cblas_{name}64_"), ctypes.c_void_p).value
        llvm.add_symbol(_PREFIX + name, address)
    llvm.add_symbol(
        _PREFIX + "dpbsv", get_cython_function_address("scipy.linalg.cython_lapack", "dpbsv")
    )
    return True


#: Whether numpy's OpenBLAS and SciPy's LAPACK are bound (module notes).
BOUND = _bind()

_i64, _i32, _f64 = ir.IntType(64), ir.IntType(32), ir.DoubleType()
_ptr = _f64.as_pointer()


def _data(context: Any, builder: Any, ty: Any, value: Any) -> Any:
    return context.make_array(ty)(context, builder, value).data


def _callee(builder: Any, name: str, ret: Any, args: list[Any]) -> Any:
    fnty = ir.FunctionType(ret, args)
    return cgutils.get_or_insert_function(builder.module, fnty, _PREFIX + name)


@intrinsic
def _ddot(typingctx: Any, n: Any, x: Any, incx: Any, y: Any, incy: Any) -> Any:
    """``cblas_ddot(n, x, incx, y, incy)`` on the arrays' data."""
    sig = types.float64(types.int64, x, types.int64, y, types.int64)

    def codegen(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        fn = _callee(builder, "ddot", _f64, [_i64, _ptr, _i64, _ptr, _i64])
        xd = _data(context, builder, sig.args[1], args[1])
        yd = _data(context, builder, sig.args[3], args[3])
        return builder.call(fn, [args[0], xd, args[2], yd, args[4]])

    return sig, codegen


@intrinsic
def _dgemv(
    typingctx: Any,
    order: Any,
    trans: Any,
    m: Any,
    n: Any,
    a: Any,
    lda: Any,
    x: Any,
    y: Any,
) -> Any:
    """``cblas_dgemv(order, trans, m, n, 1, a, lda, x, 1, 0, y, 1)`` on the arrays' data."""
    i64 = types.int64
    sig = types.void(i64, i64, i64, i64, a, i64, x, y)

    def codegen(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        i32, f64 = [_i32, _i32], [_f64]
        fn = _callee(
            builder,
            "dgemv",
            ir.VoidType(),
            [*i32, _i64, _i64, *f64, _ptr, _i64, _ptr, _i64, *f64, _ptr, _i64],
        )
        order32 = builder.trunc(args[0], _i32)
        trans32 = builder.trunc(args[1], _i32)
        one, zero, inc = ir.Constant(_f64, 1.0), ir.Constant(_f64, 0.0), ir.Constant(_i64, 1)
        ad = _data(context, builder, sig.args[4], args[4])
        xd = _data(context, builder, sig.args[6], args[6])
        yd = _data(context, builder, sig.args[7], args[7])
        builder.call(
            fn, [order32, trans32, args[2], args[3], one, ad, args[5], xd, inc, zero, yd, inc]
        )
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def _dsyrk(typingctx: Any, trans: Any, n: Any, k: Any, a: Any, lda: Any, c: Any, ldc: Any) -> Any:
    """``cblas_dsyrk(RowMajor, Upper, trans, n, k, 1, a, lda, 0, c, ldc)`` on the arrays' data."""
    i64 = types.int64
    sig = types.void(i64, i64, i64, a, i64, c, i64)

    def codegen(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        fn = _callee(
            builder,
            "dsyrk",
            ir.VoidType(),
            [_i32, _i32, _i32, _i64, _i64, _f64, _ptr, _i64, _f64, _ptr, _i64],
        )
        order, upper = ir.Constant(_i32, _ROW_MAJOR), ir.Constant(_i32, _UPPER)
        trans32 = builder.trunc(args[0], _i32)
        one, zero = ir.Constant(_f64, 1.0), ir.Constant(_f64, 0.0)
        ad = _data(context, builder, sig.args[3], args[3])
        cd = _data(context, builder, sig.args[5], args[5])
        builder.call(
            fn, [order, upper, trans32, args[1], args[2], one, ad, args[4], zero, cd, args[6]]
        )
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def _dpbsv(typingctx: Any, n: Any, kd: Any, ab: Any, ldab: Any, b: Any) -> Any:
    """LAPACK ``dpbsv('L', n, kd, 1, ab, ldab, b, n, info)``; returns ``info``."""
    i64 = types.int64
    sig = types.int64(i64, i64, ab, i64, b)

    def codegen(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        i8p, i32p = ir.IntType(8).as_pointer(), _i32.as_pointer()
        fn = _callee(
            builder, "dpbsv", ir.VoidType(), [i8p, i32p, i32p, i32p, _ptr, i32p, _ptr, i32p, i32p]
        )

        def local(value: Any) -> Any:
            return cgutils.alloca_once_value(builder, value)

        uplo = local(ir.Constant(ir.IntType(8), ord("L")))
        n32 = local(builder.trunc(args[0], _i32))
        kd32 = local(builder.trunc(args[1], _i32))
        nrhs = local(ir.Constant(_i32, 1))
        ldab32 = local(builder.trunc(args[3], _i32))
        info = local(ir.Constant(_i32, 0))
        abd = _data(context, builder, sig.args[2], args[2])
        bd = _data(context, builder, sig.args[4], args[4])
        builder.call(fn, [uplo, n32, kd32, nrhs, abd, ldab32, bd, n32, info])
        return builder.sext(builder.load(info), _i64)

    return sig, codegen


@numba.njit(cache=True)
def ddot(x: np.ndarray, y: np.ndarray) -> float:
    """``x.dot(y)`` for contiguous 1-D ``x`` and ``y``: numpy's ``0.0 + cblas_ddot``."""
    return 0.0 + _ddot(x.size, x, 1, y, 1)  # type: ignore[call-arg]


@numba.njit(cache=True)
def dot_rows(a: np.ndarray, x: np.ndarray, out: np.ndarray) -> None:
    """``out = a.dot(x)`` for a C-contiguous (m, n) ``a`` (numpy: RowMajor, NoTrans, lda n).

    numpy copies a matrix that is not one segment to C order first, so this is also
    ``b.dot(x)`` for any ``b`` with ``a = np.ascontiguousarray(b)`` that is not one segment.
    """
    m, n = a.shape
    _dgemv(_ROW_MAJOR, _NO_TRANS, m, n, a, max(n, 1), x, out)  # type: ignore[call-arg]


@numba.njit(cache=True)
def transposed_dot(a: np.ndarray, x: np.ndarray, out: np.ndarray) -> None:
    """``out = a.T.dot(x)`` for a C-contiguous (m, n) ``a``.

    ``a.T`` is Fortran-contiguous (n, m): numpy calls ColMajor, NoTrans, lda n.
    """
    m, n = a.shape
    _dgemv(_COL_MAJOR, _NO_TRANS, n, m, a, max(n, 1), x, out)  # type: ignore[call-arg]


@numba.njit(cache=True)
def gram_upper(a: np.ndarray, out: np.ndarray) -> None:
    """``out = a.T @ a`` for a C-contiguous (m, n) ``a``, ``out`` (n, n) C-contiguous.

    numpy's matmul sees one buffer and its transpose: ``cblas_dsyrk`` (RowMajor, Upper, Trans,
    n, m, lda n) into the upper triangle, then the upper copied to the lower.
    """
    m, n = a.shape
    out[:] = 0.0  # beta = 0 never reads it; zeroed so no NaN of an earlier use can matter
    _dsyrk(_TRANS, n, m, a, max(n, 1), out, max(n, 1))  # type: ignore[call-arg]
    for i in range(n):
        for j in range(i + 1, n):
            out[j, i] = out[i, j]


@numba.njit(cache=True)
def dpbsv(band: np.ndarray, rhs: np.ndarray) -> int:
    """LAPACK's ``dpbsv`` on a Fortran-ordered lower ``band`` (kd + 1, N) and ``rhs`` (N,).

    Both are overwritten (the factor, the solution), as ``scipy.linalg.lapack.dpbsv(band, rhs,
    lower=1, overwrite_ab=1, overwrite_b=1)`` does; returns LAPACK's ``info``.
    """
    kd = band.shape[0] - 1
    return _dpbsv(band.shape[1], kd, band, band.shape[0], rhs)  # type: ignore[call-arg]
