/* pyconfig.h for cross-building a stable-ABI (abi3) extension for 64-bit
 * Windows CPython with a GCC- or Clang-compatible compiler on another
 * system: what CPython's own PC/pyconfig.h says about 64-bit Windows, for
 * the limited API's headers.  The module links against python3.dll (an
 * import library made from tools/build_wheels.py's list). */
#ifndef Py_CONFIG_H
#define Py_CONFIG_H

#define MS_WIN32
#define MS_WIN64
#define MS_WINDOWS
#define NT_THREADS
#define WITH_THREAD
#define Py_ENABLE_SHARED 1
#define HAVE_DECLSPEC_DLL

#define SIZEOF_SHORT 2
#define SIZEOF_INT 4
#define SIZEOF_LONG 4           /* LLP64; Py_ssize_t is intptr_t (pyport.h) */
#define SIZEOF_LONG_LONG 8
#define SIZEOF_SIZE_T 8
#define SIZEOF_VOID_P 8
#define SIZEOF_TIME_T 8
#define SIZEOF_WCHAR_T 2
#define SIZEOF_FLOAT 4
#define SIZEOF_DOUBLE 8
#define SIZEOF_FPOS_T 8
#define SIZEOF__BOOL 1
#define SIZEOF_OFF_T 4
#define SIZEOF_HKEY 8
#define ALIGNOF_SIZE_T 8
#define ALIGNOF_LONG 4
#define HAVE_WCHAR_H 1
#define HAVE_STDDEF_H 1
#define HAVE_STDLIB_H 1
#define HAVE_SYS_STAT_H 1
#define HAVE_ERRNO_H 1
#define HAVE_FCNTL_H 1
#define HAVE_SIGNAL_H 1
#define HAVE_STDARG_PROTOTYPES 1
#define PY_FORMAT_SIZE_T "I64"
#define DOUBLE_IS_LITTLE_ENDIAN_IEEE754 1
#define PLATFORM "win32"

#endif /* Py_CONFIG_H */
