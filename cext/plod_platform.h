/* plod_platform.h -- the few operating-system services the core uses:
 * threads, a mutex and a condition variable, clocks, and files read and
 * written at an offset.  platform_posix.c implements them with POSIX
 * (Linux, macOS), platform_win32.c with Win32 (Windows); everything else in
 * the core is ISO C11 (atomics included: <stdatomic.h>).
 *
 * Every object is a value the caller owns and places (no allocation, no
 * global state).  Paths are UTF-8 on every system (what Python's
 * os.fsencode gives on Windows too).  Calls that can fail return 1 on
 * success and 0 on failure with errno set (on Windows mapped from the
 * system's error), so strerror(errno) explains them everywhere.
 */
#ifndef PLOD_PLATFORM_H
#define PLOD_PLATFORM_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#ifndef _WIN32
#include <pthread.h>
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* ---- threads ----------------------------------------------------------------
 * A plod_thread stays where it was started until plod_thread_join: the
 * new thread reads its function and argument from it. */
typedef void (*plod_thread_fn)(void *arg);

#ifdef _WIN32
typedef struct plod_thread { void *handle; plod_thread_fn fn; void *arg; } plod_thread;
typedef struct plod_mutex { void *srwlock; } plod_mutex;           /* an SRWLOCK */
typedef struct plod_cond { void *condition_variable; } plod_cond; /* a CONDITION_VARIABLE */
#else
typedef struct plod_thread { pthread_t id; plod_thread_fn fn; void *arg; } plod_thread;
typedef struct plod_mutex { pthread_mutex_t m; } plod_mutex;
typedef struct plod_cond { pthread_cond_t c; } plod_cond;
#endif

/* Runs fn(arg) on a new thread; 0 when none could start. */
int plod_thread_start(plod_thread *thread, plod_thread_fn fn, void *arg);
/* Waits for a started thread to return. */
void plod_thread_join(plod_thread *thread);

/* Not recursive.  plod_mutex_trylock: 1 when it took the lock. */
int plod_mutex_init(plod_mutex *mutex);
void plod_mutex_destroy(plod_mutex *mutex);
void plod_mutex_lock(plod_mutex *mutex);
int plod_mutex_trylock(plod_mutex *mutex);
void plod_mutex_unlock(plod_mutex *mutex);

/* plod_cond_wait releases `mutex` (held by the caller) while it waits and
 * holds it again on return; it may return without a broadcast, so callers
 * wait in a loop on their condition. */
int plod_cond_init(plod_cond *cond);
void plod_cond_destroy(plod_cond *cond);
void plod_cond_wait(plod_cond *cond, plod_mutex *mutex);
void plod_cond_broadcast(plod_cond *cond);

/* The calling process: an object that holds threads compares it to tell a
 * child of fork() (which has none of its threads) from its creator. */
unsigned long plod_process_id(void);

/* ---- time ------------------------------------------------------------------- */

/* A monotonic clock in nanoseconds (from an arbitrary origin). */
uint64_t plod_clock_ns(void);
/* CPU time the calling thread has used, in nanoseconds. */
uint64_t plod_thread_cpu_ns(void);
/* Sleeps for about `ns` nanoseconds (the system's timer may round up). */
void plod_sleep_ns(uint64_t ns);

/* ---- files ------------------------------------------------------------------ */

#ifdef _WIN32
typedef struct plod_file { void *handle; } plod_file; /* a HANDLE */
#else
typedef struct plod_file { int fd; } plod_file;
#endif

typedef enum plod_file_mode {
    PLOD_FILE_READ,   /* an existing file, read only */
    PLOD_FILE_CREATE  /* read and write; created, or emptied if it exists */
} plod_file_mode;

typedef struct plod_path_info {
    int64_t size;   /* bytes */
    int64_t mtime;  /* last modification, seconds since 1970 (UTC) */
    int regular;    /* a plain file (not a folder, device or pipe) */
} plod_path_info;

int plod_file_open(plod_file *file, const char *path, plod_file_mode mode);
/* 1 once the file is closed and written; the handle is gone either way. */
int plod_file_close(plod_file file);
/* All `bytes` at byte `offset`, or 0 (a short file counts as a failure).
 * Reads of one file may run on several threads at once. */
int plod_file_read_at(plod_file file, void *data, size_t bytes, uint64_t offset);
int plod_file_write_at(plod_file file, const void *data, size_t bytes, uint64_t offset);
/* Flushes what was written to the storage device. */
int plod_file_sync(plod_file file);
int plod_file_size(plod_file file, int64_t *size);

/* stdio's fopen for a UTF-8 path. */
FILE *plod_fopen(const char *path, const char *mode);
int plod_path_info_get(const char *path, plod_path_info *info);
/* 1 when the file exists and this process may read it. */
int plod_path_readable(const char *path);
/* Renames `from` to `to`, replacing a file at `to`. */
int plod_path_replace(const char *from, const char *to);
int plod_path_remove(const char *path);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_PLATFORM_H */
