/* The little the native binaries need from the operating system beyond standard C, written once for
 * Linux (POSIX) and once for Windows (compiled with mingw-w64), so that the files including it read the
 * same on both: a lock, loading a binary and looking up its functions, whether a file can be read, strndup.
 * Paths are UTF-8 on both systems; on Windows they are converted to UTF-16 for the wide-character API (the
 * narrow one would read them in the ANSI code page). */
#ifndef WINGSIM_NATIVE_PLATFORM_H
#define WINGSIM_NATIVE_PLATFORM_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>

typedef SRWLOCK Lock;
#define LOCK_INITIALIZER SRWLOCK_INIT
static inline void lock(Lock *l) { AcquireSRWLockExclusive(l); }
static inline void unlock(Lock *l) { ReleaseSRWLockExclusive(l); }

/* `utf8` as a new UTF-16 string (free it), or NULL. */
static inline wchar_t *wide_string(const char *utf8)
{
    int n = MultiByteToWideChar(CP_UTF8, MB_ERR_INVALID_CHARS, utf8, -1, NULL, 0);
    wchar_t *w = n > 0 ? malloc((size_t)n * sizeof *w) : NULL;
    if (w != NULL && MultiByteToWideChar(CP_UTF8, MB_ERR_INVALID_CHARS, utf8, -1, w, n) != n) {
        free(w);
        w = NULL;
    }
    return w;
}

/* `wide` as UTF-8 into `out` (`size` bytes); 0 if it does not fit. */
static inline int utf8_string(const wchar_t *wide, char *out, size_t size)
{
    return WideCharToMultiByte(CP_UTF8, 0, wide, -1, out, (int)size, NULL, NULL) > 0;
}

static inline int file_readable(const char *path)
{
    wchar_t *w = wide_string(path);
    DWORD attributes = w != NULL ? GetFileAttributesW(w) : INVALID_FILE_ATTRIBUTES;
    free(w);
    return attributes != INVALID_FILE_ATTRIBUTES;
}

/* Load the binary `path`; NULL with the reason in `error` on failure. Its own imports are looked for in its
 * folder first (LOAD_WITH_ALTERED_SEARCH_PATH), as a Linux binary finds them through its RPATH. */
static inline void *library_open(const char *path, char *error, size_t size)
{
    wchar_t *w = wide_string(path);
    HMODULE handle = w != NULL ? LoadLibraryExW(w, NULL, LOAD_WITH_ALTERED_SEARCH_PATH) : NULL;
    if (handle == NULL) snprintf(error, size, "cannot load %s: Windows error %lu", path, GetLastError());
    free(w);
    return (void *)handle;
}

static inline void *library_symbol(void *handle, const char *name)
{
    return (void *)GetProcAddress((HMODULE)handle, name);
}

static inline char *strndup(const char *s, size_t n)
{
    size_t k = strnlen(s, n);
    char *copy = malloc(k + 1);
    if (copy != NULL) {
        memcpy(copy, s, k);
        copy[k] = '\0';
    }
    return copy;
}

#else
#include <dlfcn.h>
#include <pthread.h>
#include <unistd.h>

typedef pthread_mutex_t Lock;
#define LOCK_INITIALIZER PTHREAD_MUTEX_INITIALIZER
static inline void lock(Lock *l) { pthread_mutex_lock(l); }
static inline void unlock(Lock *l) { pthread_mutex_unlock(l); }

static inline int file_readable(const char *path) { return access(path, R_OK) == 0; }

static inline void *library_open(const char *path, char *error, size_t size)
{
    void *handle = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (handle == NULL) snprintf(error, size, "cannot load %s: %s", path, dlerror());
    return handle;
}

static inline void *library_symbol(void *handle, const char *name) { return dlsym(handle, name); }
#endif

#endif
