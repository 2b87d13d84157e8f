/* platform_win32.c -- plod_platform.h on Windows: Win32 threads, slim
 * reader/writer locks and condition variables (Windows Vista on), the
 * performance counter, and overlapped-offset ReadFile / WriteFile on file
 * handles.  Paths arrive as UTF-8 and go to the wide (UTF-16) calls. */
#ifdef _WIN32
#include "plod_platform.h"

#define WIN32_LEAN_AND_MEAN
#include <windows.h>

#include <errno.h>
#include <stdlib.h>

_Static_assert(sizeof(plod_mutex) == sizeof(SRWLOCK), "plod_mutex holds an SRWLOCK");
_Static_assert(sizeof(plod_cond) == sizeof(CONDITION_VARIABLE),
               "plod_cond holds a CONDITION_VARIABLE");

#define PLOD__SRW(mutex) ((SRWLOCK *)&(mutex)->srwlock)
#define PLOD__CV(cond) ((CONDITION_VARIABLE *)&(cond)->condition_variable)

/* errno for the calling thread's last Win32 error, so callers' messages
 * read as on POSIX. */
static void plod__set_errno(void)
{
    switch (GetLastError()) {
    case ERROR_FILE_NOT_FOUND:
    case ERROR_PATH_NOT_FOUND:
    case ERROR_INVALID_NAME:
        errno = ENOENT;
        break;
    case ERROR_ACCESS_DENIED:
    case ERROR_SHARING_VIOLATION:
    case ERROR_LOCK_VIOLATION:
        errno = EACCES;
        break;
    case ERROR_FILE_EXISTS:
    case ERROR_ALREADY_EXISTS:
        errno = EEXIST;
        break;
    case ERROR_NOT_ENOUGH_MEMORY:
    case ERROR_OUTOFMEMORY:
        errno = ENOMEM;
        break;
    case ERROR_DISK_FULL:
    case ERROR_HANDLE_DISK_FULL:
        errno = ENOSPC;
        break;
    default:
        errno = EIO;
    }
}

/* ---- threads ---------------------------------------------------------------- */

static DWORD WINAPI plod__thread_main(LPVOID arg)
{
    plod_thread *thread = arg;
    thread->fn(thread->arg);
    return 0;
}

int plod_thread_start(plod_thread *thread, plod_thread_fn fn, void *arg)
{
    thread->fn = fn;
    thread->arg = arg;
    thread->handle = CreateThread(NULL, 0, plod__thread_main, thread, 0, NULL);
    return thread->handle != NULL;
}

void plod_thread_join(plod_thread *thread)
{
    WaitForSingleObject(thread->handle, INFINITE);
    CloseHandle(thread->handle);
}

int plod_mutex_init(plod_mutex *mutex)
{
    InitializeSRWLock(PLOD__SRW(mutex));
    return 1;
}

void plod_mutex_destroy(plod_mutex *mutex) { (void)mutex; /* an SRWLOCK holds nothing */ }
void plod_mutex_lock(plod_mutex *mutex) { AcquireSRWLockExclusive(PLOD__SRW(mutex)); }
int plod_mutex_trylock(plod_mutex *mutex) { return TryAcquireSRWLockExclusive(PLOD__SRW(mutex)) != 0; }
void plod_mutex_unlock(plod_mutex *mutex) { ReleaseSRWLockExclusive(PLOD__SRW(mutex)); }

int plod_cond_init(plod_cond *cond)
{
    InitializeConditionVariable(PLOD__CV(cond));
    return 1;
}

void plod_cond_destroy(plod_cond *cond) { (void)cond; }

void plod_cond_wait(plod_cond *cond, plod_mutex *mutex)
{
    SleepConditionVariableSRW(PLOD__CV(cond), PLOD__SRW(mutex), INFINITE, 0);
}

void plod_cond_broadcast(plod_cond *cond) { WakeAllConditionVariable(PLOD__CV(cond)); }

unsigned long plod_process_id(void)
{
    return (unsigned long)GetCurrentProcessId();
}

/* ---- time ------------------------------------------------------------------- */

uint64_t plod_clock_ns(void)
{
    LARGE_INTEGER frequency, count;
    QueryPerformanceFrequency(&frequency); /* fixed at boot; cheap to ask */
    QueryPerformanceCounter(&count);
    uint64_t f = (uint64_t)frequency.QuadPart, c = (uint64_t)count.QuadPart;
    return c / f * 1000000000u + c % f * 1000000000u / f;
}

uint64_t plod_thread_cpu_ns(void)
{
    FILETIME created, exited, kernel, user;
    if (!GetThreadTimes(GetCurrentThread(), &created, &exited, &kernel, &user))
        return 0;
    uint64_t k = (uint64_t)kernel.dwHighDateTime << 32 | kernel.dwLowDateTime;
    uint64_t u = (uint64_t)user.dwHighDateTime << 32 | user.dwLowDateTime;
    return (k + u) * 100u; /* FILETIME counts 100 ns */
}

void plod_sleep_ns(uint64_t ns)
{
    /* Sleep counts milliseconds (and the timer ticks coarser still):
     * rounded up, so a short nap never turns into a busy loop */
    Sleep((DWORD)((ns + 999999u) / 1000000u));
}

/* ---- files ------------------------------------------------------------------ */

/* The path as UTF-16, malloc'ed; NULL (errno set) when it is not UTF-8. */
static wchar_t *plod__wide(const char *path)
{
    int n = MultiByteToWideChar(CP_UTF8, MB_ERR_INVALID_CHARS, path, -1, NULL, 0);
    if (n <= 0) {
        errno = ENOENT;
        return NULL;
    }
    wchar_t *wide = malloc((size_t)n * sizeof *wide);
    if (!wide) {
        errno = ENOMEM;
        return NULL;
    }
    MultiByteToWideChar(CP_UTF8, MB_ERR_INVALID_CHARS, path, -1, wide, n);
    return wide;
}

int plod_file_open(plod_file *file, const char *path, plod_file_mode mode)
{
    file->handle = INVALID_HANDLE_VALUE;
    wchar_t *wide = plod__wide(path);
    if (!wide)
        return 0;
    DWORD access = mode == PLOD_FILE_CREATE ? GENERIC_READ | GENERIC_WRITE : GENERIC_READ;
    DWORD disposition = mode == PLOD_FILE_CREATE ? CREATE_ALWAYS : OPEN_EXISTING;
    /* others may read, rename or delete it meanwhile, as on POSIX */
    DWORD share = FILE_SHARE_READ | FILE_SHARE_WRITE | FILE_SHARE_DELETE;
    HANDLE h = CreateFileW(wide, access, share, NULL, disposition, FILE_ATTRIBUTE_NORMAL, NULL);
    if (h == INVALID_HANDLE_VALUE)
        plod__set_errno();
    free(wide);
    file->handle = h;
    return h != INVALID_HANDLE_VALUE;
}

int plod_file_close(plod_file file)
{
    if (!CloseHandle(file.handle)) {
        plod__set_errno();
        return 0;
    }
    return 1;
}

/* ReadFile / WriteFile take at most 4 GiB - 1 a call */
#define PLOD__IO_MAX ((size_t)1 << 30)

int plod_file_read_at(plod_file file, void *data, size_t bytes, uint64_t offset)
{
    unsigned char *p = data;
    while (bytes) {
        OVERLAPPED at = {0};
        at.Offset = (DWORD)offset;
        at.OffsetHigh = (DWORD)(offset >> 32);
        DWORD n = 0;
        DWORD ask = (DWORD)(bytes < PLOD__IO_MAX ? bytes : PLOD__IO_MAX);
        if (!ReadFile(file.handle, p, ask, &n, &at)) {
            plod__set_errno();
            return 0;
        }
        if (n == 0) {
            errno = EIO; /* the file ends before the bytes asked for */
            return 0;
        }
        p += n, bytes -= n, offset += n;
    }
    return 1;
}

int plod_file_write_at(plod_file file, const void *data, size_t bytes, uint64_t offset)
{
    const unsigned char *p = data;
    while (bytes) {
        OVERLAPPED at = {0};
        at.Offset = (DWORD)offset;
        at.OffsetHigh = (DWORD)(offset >> 32);
        DWORD n = 0;
        DWORD ask = (DWORD)(bytes < PLOD__IO_MAX ? bytes : PLOD__IO_MAX);
        if (!WriteFile(file.handle, p, ask, &n, &at)) {
            plod__set_errno();
            return 0;
        }
        if (n == 0) {
            errno = EIO;
            return 0;
        }
        p += n, bytes -= n, offset += n;
    }
    return 1;
}

int plod_file_sync(plod_file file)
{
    if (!FlushFileBuffers(file.handle)) {
        plod__set_errno();
        return 0;
    }
    return 1;
}

int plod_file_size(plod_file file, int64_t *size)
{
    LARGE_INTEGER n;
    if (!GetFileSizeEx(file.handle, &n)) {
        plod__set_errno();
        return 0;
    }
    *size = (int64_t)n.QuadPart;
    return 1;
}

FILE *plod_fopen(const char *path, const char *mode)
{
    wchar_t *wide = plod__wide(path);
    wchar_t wide_mode[8];
    size_t i = 0;
    for (; mode[i] && i + 1 < sizeof wide_mode / sizeof *wide_mode; i++)
        wide_mode[i] = (wchar_t)(unsigned char)mode[i];
    wide_mode[i] = 0;
    FILE *f = wide ? _wfopen(wide, wide_mode) : NULL;
    free(wide);
    return f;
}

/* FILETIME (100 ns since 1601) to seconds since 1970 */
static int64_t plod__unix_seconds(FILETIME t)
{
    uint64_t ticks = (uint64_t)t.dwHighDateTime << 32 | t.dwLowDateTime;
    return (int64_t)(ticks / 10000000u) - INT64_C(11644473600);
}

int plod_path_info_get(const char *path, plod_path_info *info)
{
    wchar_t *wide = plod__wide(path);
    if (!wide)
        return 0;
    WIN32_FILE_ATTRIBUTE_DATA data;
    BOOL ok = GetFileAttributesExW(wide, GetFileExInfoStandard, &data);
    if (!ok)
        plod__set_errno();
    free(wide);
    if (!ok)
        return 0;
    info->size = (int64_t)((uint64_t)data.nFileSizeHigh << 32 | data.nFileSizeLow);
    info->mtime = plod__unix_seconds(data.ftLastWriteTime);
    info->regular = !(data.dwFileAttributes & (FILE_ATTRIBUTE_DIRECTORY | FILE_ATTRIBUTE_DEVICE));
    return 1;
}

int plod_path_readable(const char *path)
{
    plod_file file;
    if (!plod_file_open(&file, path, PLOD_FILE_READ))
        return 0;
    plod_file_close(file);
    return 1;
}

int plod_path_replace(const char *from, const char *to)
{
    wchar_t *wide_from = plod__wide(from), *wide_to = wide_from ? plod__wide(to) : NULL;
    BOOL ok = wide_to && MoveFileExW(wide_from, wide_to, MOVEFILE_REPLACE_EXISTING);
    if (wide_to && !ok)
        plod__set_errno();
    free(wide_from);
    free(wide_to);
    return ok != 0;
}

int plod_path_remove(const char *path)
{
    wchar_t *wide = plod__wide(path);
    BOOL ok = wide && DeleteFileW(wide);
    if (wide && !ok)
        plod__set_errno();
    free(wide);
    return ok != 0;
}
#endif /* _WIN32 */
