/* platform_posix.c -- plod_platform.h on POSIX systems (Linux, macOS):
 * pthreads, clock_gettime, and pread / pwrite on file descriptors. */
#ifndef _WIN32
#include "plod_platform.h"

#include <errno.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

/* ---- threads ---------------------------------------------------------------- */

static void *plod__thread_main(void *arg)
{
    plod_thread *thread = arg;
    thread->fn(thread->arg);
    return NULL;
}

int plod_thread_start(plod_thread *thread, plod_thread_fn fn, void *arg)
{
    thread->fn = fn;
    thread->arg = arg;
    return pthread_create(&thread->id, NULL, plod__thread_main, thread) == 0;
}

void plod_thread_join(plod_thread *thread)
{
    pthread_join(thread->id, NULL);
}

int plod_mutex_init(plod_mutex *mutex) { return pthread_mutex_init(&mutex->m, NULL) == 0; }
void plod_mutex_destroy(plod_mutex *mutex) { pthread_mutex_destroy(&mutex->m); }
void plod_mutex_lock(plod_mutex *mutex) { pthread_mutex_lock(&mutex->m); }
int plod_mutex_trylock(plod_mutex *mutex) { return pthread_mutex_trylock(&mutex->m) == 0; }
void plod_mutex_unlock(plod_mutex *mutex) { pthread_mutex_unlock(&mutex->m); }

int plod_cond_init(plod_cond *cond) { return pthread_cond_init(&cond->c, NULL) == 0; }
void plod_cond_destroy(plod_cond *cond) { pthread_cond_destroy(&cond->c); }
void plod_cond_wait(plod_cond *cond, plod_mutex *mutex) { pthread_cond_wait(&cond->c, &mutex->m); }
void plod_cond_broadcast(plod_cond *cond) { pthread_cond_broadcast(&cond->c); }

unsigned long plod_process_id(void)
{
    return (unsigned long)getpid();
}

/* ---- time ------------------------------------------------------------------- */

static uint64_t plod__clock(clockid_t clock)
{
    struct timespec ts;
    clock_gettime(clock, &ts);
    return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

uint64_t plod_clock_ns(void) { return plod__clock(CLOCK_MONOTONIC); }
uint64_t plod_thread_cpu_ns(void) { return plod__clock(CLOCK_THREAD_CPUTIME_ID); }

void plod_sleep_ns(uint64_t ns)
{
    struct timespec nap = {(time_t)(ns / 1000000000u), (long)(ns % 1000000000u)};
    nanosleep(&nap, NULL);
}

/* ---- files ------------------------------------------------------------------ */

int plod_file_open(plod_file *file, const char *path, plod_file_mode mode)
{
    int flags = mode == PLOD_FILE_CREATE ? O_RDWR | O_CREAT | O_TRUNC : O_RDONLY;
    file->fd = open(path, flags, 0644);
    return file->fd >= 0;
}

int plod_file_close(plod_file file)
{
    return close(file.fd) == 0;
}

int plod_file_read_at(plod_file file, void *data, size_t bytes, uint64_t offset)
{
    unsigned char *p = data;
    while (bytes) {
        ssize_t n = pread(file.fd, p, bytes, (off_t)offset);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0) {
            if (n == 0)
                errno = EIO; /* the file ends before the bytes asked for */
            return 0;
        }
        p += n, bytes -= (size_t)n, offset += (uint64_t)n;
    }
    return 1;
}

int plod_file_write_at(plod_file file, const void *data, size_t bytes, uint64_t offset)
{
    const unsigned char *p = data;
    while (bytes) {
        ssize_t n = pwrite(file.fd, p, bytes, (off_t)offset);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0) {
            if (n == 0)
                errno = EIO;
            return 0;
        }
        p += n, bytes -= (size_t)n, offset += (uint64_t)n;
    }
    return 1;
}

int plod_file_sync(plod_file file)
{
    return fsync(file.fd) == 0;
}

int plod_file_size(plod_file file, int64_t *size)
{
    struct stat info;
    if (fstat(file.fd, &info) != 0)
        return 0;
    *size = (int64_t)info.st_size;
    return 1;
}

FILE *plod_fopen(const char *path, const char *mode)
{
    return fopen(path, mode);
}

int plod_path_info_get(const char *path, plod_path_info *info)
{
    struct stat st;
    if (stat(path, &st) != 0)
        return 0;
    info->size = (int64_t)st.st_size;
    info->mtime = (int64_t)st.st_mtime;
    info->regular = S_ISREG(st.st_mode) != 0;
    return 1;
}

int plod_path_readable(const char *path)
{
    return access(path, R_OK) == 0;
}

int plod_path_replace(const char *from, const char *to)
{
    return rename(from, to) == 0;
}

int plod_path_remove(const char *path)
{
    return unlink(path) == 0;
}
#endif /* !_WIN32 */
