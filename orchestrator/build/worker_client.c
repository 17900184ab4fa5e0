/* The host side of a standalone FMU: every FMI call of an instance is carried out by a worker process
 * (fmi_worker.c) over the channel of worker_channel.h. fmi_shim.c, compiled with SHIM_WORKER, forwards to
 * the functions of `worker_table` as it forwards to pythonfmu's binary in an ordinary FMU, with the same
 * checks and status rule.
 *
 * fmi2Instantiate joins a worker of this host process that serves FMUs of the same runtime
 * (SHIM_WORKER_KEY) and accepts this one (no instance of this FMU yet, the same code in every Python
 * package they share: SHIM_PACKAGES), or starts one: `<folder of this binary>/SHIM_WORKER`, started with
 * posix_spawn (no fork of the host's memory), an empty environment but for the host's WINGSIM_* variables,
 * one BLAS thread and the runtime's library folder (LD_LIBRARY_PATH), default signal dispositions, and a
 * process group of its own. A worker ends
 *   - after the fmi2FreeInstance of its last instance (asked to; killed if it has not ended within
 *     WORKER_EXIT_WAIT_MS), reaped by the client that freed it;
 *   - when the host process ends in any way, SIGKILL included: the host holds the only write end of its
 *     lifeline pipe, and the kernel closes it with the process (the worker then exits at once);
 * and a client sees it end, in any way, when its connection hangs up. Then the call returns fmi2Fatal with
 * the reason logged (exit status or signal, and the end of the worker's output), and every later call of
 * the instance is refused.
 *
 * Exchanges are what cost in a coupled step, so Real values are cached: the host reads the same outputs
 * after every step, and the client asks the worker to send them with the answer of each call that
 * changes the unit (fmi2DoStep, ...; the prefetch list: the value references read since the list began,
 * where they read without a message). fmi2GetReal of cached values then answers without an exchange, with
 * the values the worker would give: nothing changes them between the call that sent them and the next
 * call that may change the unit, which invalidates the cache (`epoch`).
 *
 * That much is the same on Windows, where only the worker's life differs (worker_client_win.c, included
 * in place of the Linux section below): every instance starts a worker of its own.
 */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifndef _WIN32
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#endif

#include "fmi2_table.h"
#include "native_platform.h"
#include "worker_channel.h"

#if !defined(SHIM_WORKER) || !defined(SHIM_INNER) || !defined(SHIM_WORKER_KEY) || !defined(SHIM_PACKAGES)
#error "SHIM_WORKER, SHIM_INNER, SHIM_WORKER_KEY and SHIM_PACKAGES must be defined"
#endif

#define MAX_CACHED_REFERENCE (1u << 20) /* Real value references above are never cached */
#define WORKER_EXIT_WAIT_MS 5000
#define OUTPUT_TAIL 1500                 /* bytes of the worker's output logged when it ends */
#define MAX_WORKERS 64                   /* workers of one runtime a host process may have */

typedef struct {
    Channel ch;                          /* this instance's channel */
#ifdef _WIN32
    HANDLE process;                      /* the worker's */
    DWORD pid;
    HANDLE job;                          /* kills the worker when the host process ends, however */
    HANDLE control_section;
    HANDLE output;                       /* the worker's stdout and stderr: a temporary file */
#else
    pid_t pid;                           /* the worker's */
    int connection;                      /* to the worker: hangs up when it ends */
    int output;                          /* the worker's stdout and stderr */
#endif
    WorkerControl *control;              /* the worker's doorbell */
    ChannelEvent wake_worker, wake_client;   /* Windows: the events each side sleeps on */
    int gone;                            /* the worker has ended: every call is refused */
    const fmi2CallbackFunctions *callbacks;
    char *name;
    uint32_t request;                    /* number of the last request */
    /* the Real value cache: value[vr] is valid while cached[vr] == epoch */
    uint64_t epoch;
    size_t n_slots;
    double *value;
    uint64_t *cached;
    unsigned char *listed;               /* vr is on the prefetch list */
    fmi2ValueReference *list;
    uint32_t n_list, cap_list;
    int list_changed;                    /* the worker has not received the list as it is */
    char **strings;                      /* strings of the last call that returned some */
    size_t n_strings;
} Worker;

static void tell(const Worker *w, fmi2Status status, const char *format, ...)
{
    char text[4096], escaped[8192];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    size_t k = 0;                        /* the logger takes the text as a printf format */
    for (const char *p = text; *p != '\0' && k + 2 < sizeof escaped; ++p) {
        if (*p == '%') escaped[k++] = '%';
        escaped[k++] = *p;
    }
    escaped[k] = '\0';
    if (w->callbacks != NULL && w->callbacks->logger != NULL)
        w->callbacks->logger(w->callbacks->componentEnvironment, w->name, status,
                             status >= fmi2Fatal ? "logStatusFatal" : "logStatusError", escaped);
}

/* The instance's own memory: what both platforms' `release` free last. */
static void free_worker(Worker *w)
{
    for (size_t i = 0; i < w->n_strings; ++i) free(w->strings[i]);
    free(w->strings);
    free(w->value);
    free(w->cached);
    free(w->listed);
    free(w->list);
    free(w->name);
    free(w);
}

/* ---- the worker's life ---------------------------------------------------------------------------- */

#ifdef _WIN32
#include "worker_client_win.c"
#else
extern char **environ;

/* The write ends of the lifelines of the workers this binary started, kept until those workers have
 * ended: closing one would end a worker that still serves instances of other FMUs. */
static pthread_mutex_t lifelines_lock = PTHREAD_MUTEX_INITIALIZER;
static int lifelines[MAX_WORKERS];
static int n_lifelines = 0;

/* Close the lifelines whose worker has ended (its read end closed: the write end reports an error). */
static void close_ended_lifelines(void)
{
    pthread_mutex_lock(&lifelines_lock);
    for (int i = 0; i < n_lifelines;) {
        struct pollfd p = {lifelines[i], 0, 0};
        if (poll(&p, 1, 0) > 0 && (p.revents & (POLLERR | POLLHUP))) {
            close(lifelines[i]);
            lifelines[i] = lifelines[--n_lifelines];
        } else {
            ++i;
        }
    }
    pthread_mutex_unlock(&lifelines_lock);
}

static int worker_alive(void *arg)
{
    Worker *w = (Worker *)arg;
    struct pollfd p = {w->connection, POLLIN, 0};
    return poll(&p, 1, 0) == 0;
}

/* Wait up to `ms` for the worker to end, then reap it (it is this process's child, whichever binary
 * started it); its wait status, shared with the other clients through its control page, or -1 if
 * another part of the host reaped it (a SIGCHLD handler, SIGCHLD ignored). */
static int reap(Worker *w, int ms)
{
    struct pollfd p = {w->connection, POLLIN, 0};
    while (poll(&p, 1, ms) < 0 && errno == EINTR) {
    }
    int status;
    pid_t done;
    while ((done = waitpid(w->pid, &status, WNOHANG)) < 0 && errno == EINTR) {
    }
    if (done == 0 && ms > 0 && !worker_alive(w)) {   /* hung up: ending, give it a moment */
        struct timespec pause = {0, 20000000};
        for (int k = 0; k < 50 && done == 0; ++k) {
            nanosleep(&pause, NULL);
            done = waitpid(w->pid, &status, WNOHANG);
        }
    }
    if (done == 0 && ms > 0) {           /* still running after `ms`: it will not end by itself */
        kill(w->pid, SIGKILL);
        while ((done = waitpid(w->pid, &status, 0)) < 0 && errno == EINTR) {
        }
    }
    if (done == w->pid) atomic_store(&w->control->exit_status, status);
    close_ended_lifelines();
    int shared = atomic_load(&w->control->exit_status);
    return done == w->pid ? status : shared;
}

/* The worker ended during `function`: reap it and log why, with the end of its output. */
static fmi2Status ended(Worker *w, const char *function)
{
    if (w->gone) return fmi2Fatal;
    w->gone = 1;
    int status = reap(w, 1000);
    char why[256], tail[OUTPUT_TAIL + 1] = "";
    if (status == -1) snprintf(why, sizeof why, "ended (its exit status was collected by the host)");
    else if (WIFSIGNALED(status))
        snprintf(why, sizeof why, "was killed by signal %d (%s)", WTERMSIG(status), strsignal(WTERMSIG(status)));
    else snprintf(why, sizeof why, "exited with status %d", WEXITSTATUS(status));
    off_t size = w->output >= 0 ? lseek(w->output, 0, SEEK_END) : 0;
    off_t from = size > OUTPUT_TAIL ? size - OUTPUT_TAIL : 0;
    ssize_t got = size > 0 ? pread(w->output, tail, (size_t)(size - from), from) : 0;
    tail[got > 0 ? got : 0] = '\0';
    tell(w, fmi2Fatal, "%s: the unit's worker process (pid %d) %s; the instance cannot be used any more%s%s",
         function, (int)w->pid, why, tail[0] != '\0' ? ". Its last output: " : "", tail);
    return fmi2Fatal;
}

/* The folder of this binary, with a trailing '/'. */
static int binary_folder(char *path, size_t size)
{
    Dl_info info;
    if (!dladdr((void *)&binary_folder, &info) || info.dli_fname == NULL) return 0;
    const char *slash = strrchr(info.dli_fname, '/');
    size_t n = slash != NULL ? (size_t)(slash - info.dli_fname) + 1 : 0;
    if (n + 1 > size) return 0;
    memcpy(path, info.dli_fname, n);
    path[n] = '\0';
    return 1;
}

/* A descriptor of `fd` numbered 10 or above, close-on-exec: posix_spawn's dup2 to 3..5 then never
 * overwrites a source it has still to copy. */
static int high(int fd)
{
    int copy = fcntl(fd, F_DUPFD_CLOEXEC, 10);
    close(fd);
    return copy;
}

/* Start a worker listening at `listening` (bound and listening); 0, the reason logged, on failure. */
static int start_worker(Worker *w, const char *folder, int listening)
{
    char worker[4096], inner[4096], runtime[4096];
    snprintf(worker, sizeof worker, "%s%s", folder, SHIM_WORKER);
    snprintf(inner, sizeof inner, "%s%s", folder, SHIM_INNER);
    snprintf(runtime, sizeof runtime, "%sruntime", folder);
    struct stat info;
    if (stat(worker, &info) != 0 || stat(runtime, &info) != 0) {
        tell(w, fmi2Error, "fmi2Instantiate: the FMU's worker or runtime is missing: %s, %s (an incomplete "
                           "FMU: rebuild it with wingsim build --standalone)", worker, runtime);
        return 0;
    }
    /* zip tools often drop the executable bit on unpacking */
    if (access(worker, X_OK) != 0 && chmod(worker, 0755) != 0) {
        tell(w, fmi2Error, "fmi2Instantiate: the worker %s is not executable and cannot be made so: %s", worker,
             strerror(errno));
        return 0;
    }
    int lifeline[2];
    int control = high(memfd_create("wingsim-worker-control", MFD_CLOEXEC));
    int output = high(memfd_create("wingsim-worker-output", MFD_CLOEXEC));
    if (control < 0 || output < 0 || ftruncate(control, WORKER_CONTROL_SIZE) != 0
        || pipe2(lifeline, O_CLOEXEC) != 0) {
        tell(w, fmi2Error, "fmi2Instantiate: cannot create the worker's control page: %s", strerror(errno));
        if (control >= 0) close(control);
        if (output >= 0) close(output);
        return 0;
    }
    WorkerControl *page = mmap(NULL, WORKER_CONTROL_SIZE, PROT_READ | PROT_WRITE, MAP_SHARED, control, 0);
    if (page != MAP_FAILED) {
        page->magic = CHANNEL_MAGIC;
        page->version = CHANNEL_VERSION;
        atomic_store(&page->exit_status, -1);
        munmap(page, WORKER_CONTROL_SIZE);
    }
    int child_lifeline = high(lifeline[0]), own_lifeline = lifeline[1];

    /* the environment: WINGSIM_* from the host, one BLAS thread, glibc's allocator thresholds of the
     * processes wingsim owns (orchestrator/run/allocator.py: the solvers' temporaries stay in the heap), the
     * runtime's libraries found first by every extension module (the worker's RPATH covers only its own
     * needs); nothing else reaches the unit */
    size_t n_env = 0;
    for (char **e = environ; e != NULL && *e != NULL; ++e) n_env += strncmp(*e, "WINGSIM_", 8) == 0;
    char **env = calloc(n_env + 6, sizeof *env);
    char libraries[4200];
    snprintf(libraries, sizeof libraries, "LD_LIBRARY_PATH=%s/lib", runtime);
    size_t k = 0;
    if (env != NULL) {
        for (char **e = environ; e != NULL && *e != NULL; ++e)
            if (strncmp(*e, "WINGSIM_", 8) == 0) env[k++] = *e;
        env[k++] = "OPENBLAS_NUM_THREADS=1";
        env[k++] = "OMP_NUM_THREADS=1";
        env[k++] = "MALLOC_MMAP_THRESHOLD_=33554432";
        env[k++] = "MALLOC_TRIM_THRESHOLD_=67108864";
        env[k++] = libraries;
    }
    posix_spawn_file_actions_t actions;
    posix_spawnattr_t attributes;
    sigset_t none, all;
    sigemptyset(&none);
    sigfillset(&all);
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_adddup2(&actions, output, 1);
    posix_spawn_file_actions_adddup2(&actions, output, 2);
    posix_spawn_file_actions_adddup2(&actions, child_lifeline, 3);
    posix_spawn_file_actions_adddup2(&actions, control, 4);
    posix_spawn_file_actions_adddup2(&actions, listening, 5);
    posix_spawnattr_init(&attributes);
    posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETPGROUP);
    posix_spawnattr_setsigmask(&attributes, &none);
    posix_spawnattr_setsigdefault(&attributes, &all);
    posix_spawnattr_setpgroup(&attributes, 0);
    char *argv[] = {worker, inner, runtime, NULL};
    pid_t pid = 0;
    int failed = env == NULL ? ENOMEM : posix_spawn(&pid, worker, &actions, &attributes, argv, env);
    posix_spawn_file_actions_destroy(&actions);
    posix_spawnattr_destroy(&attributes);
    free(env);
    close(child_lifeline);               /* the worker's: only it holds them now */
    close(control);
    close(output);
    if (failed != 0) {
        close(own_lifeline);
        tell(w, fmi2Error, "fmi2Instantiate: cannot start the worker %s: %s", worker, strerror(failed));
        return 0;
    }
    pthread_mutex_lock(&lifelines_lock);
    if (n_lifelines < MAX_WORKERS) lifelines[n_lifelines++] = own_lifeline;
    pthread_mutex_unlock(&lifelines_lock);
    return 1;
}

/* Join the worker listening at `address`: 1 if it accepts this instance (w->connection, control, output
 * and pid set), 0 if it refuses or is not there. */
static int join(Worker *w, const struct sockaddr_un *address, socklen_t length)
{
    int connection = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (connection < 0 || connect(connection, (const struct sockaddr *)address, length) != 0) {
        if (connection >= 0) close(connection);
        return 0;
    }
    JoinRequest request = {CHANNEL_MAGIC, CHANNEL_VERSION, "", ""};
    snprintf(request.guid, sizeof request.guid, "%s", SHIM_GUID);
    snprintf(request.packages, sizeof request.packages, "%s", SHIM_PACKAGES);
    JoinReply reply;
    int fds[2], n_fds = 0;
    if (!send_with_fds(connection, &request, sizeof request, &w->ch.fd, 1)
        || !receive_with_fds(connection, &reply, sizeof reply, fds, 2, &n_fds) || !reply.accepted || n_fds != 2) {
        for (int i = 0; i < n_fds; ++i) close(fds[i]);
        close(connection);
        return 0;
    }
    w->control = mmap(NULL, WORKER_CONTROL_SIZE, PROT_READ | PROT_WRITE, MAP_SHARED, fds[0], 0);
    close(fds[0]);
    if (w->control == MAP_FAILED) {
        w->control = NULL;
        close(fds[1]);
        close(connection);
        return 0;
    }
    w->connection = connection;
    w->output = fds[1];
    w->pid = reply.pid;
    return 1;
}

/* This instance's channel: a shared memory file, mapped. */
static int open_channel(Worker *w)
{
    w->ch.fd = high(memfd_create("wingsim-channel", MFD_CLOEXEC));
    if (w->ch.fd < 0 || ftruncate(w->ch.fd, CHANNEL_INITIAL_SIZE) != 0 || !channel_map(&w->ch, CHANNEL_INITIAL_SIZE)) {
        tell(w, fmi2Error, "fmi2Instantiate: cannot create the channel to the worker: %s", strerror(errno));
        return 0;
    }
    return 1;
}

/* Join a worker of this host process that accepts this instance, or start one and join it. */
static int find_worker(Worker *w, const char *folder)
{
    close_ended_lifelines();
    long host = (long)getpid();
    for (int attempt = 0; attempt < 3; ++attempt) {
        int free_number = -1;
        for (int number = 0; number < MAX_WORKERS; ++number) {
            struct sockaddr_un address;
            socklen_t length = worker_address(&address, host, SHIM_WORKER_KEY, number);
            int probe = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
            int listening = probe >= 0 && bind(probe, (struct sockaddr *)&address, length) == 0;
            if (listening) {                 /* nobody there: the first free number, keep looking */
                close(probe);
                if (free_number < 0) free_number = number;
                continue;
            }
            if (probe >= 0) close(probe);
            if (join(w, &address, length)) return 1;
        }
        if (free_number < 0) break;
        struct sockaddr_un address;
        socklen_t length = worker_address(&address, host, SHIM_WORKER_KEY, free_number);
        int listening = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
        if (listening < 0) break;
        if (bind(listening, (struct sockaddr *)&address, length) != 0 || listen(listening, 16) != 0) {
            close(listening);                /* another client took that number meanwhile: look again */
            continue;
        }
        int listening_high = high(listening);
        int started = start_worker(w, folder, listening_high);
        int joined = started && join(w, &address, length);   /* queued until the worker accepts */
        close(listening_high);
        if (!started) return 0;
        if (joined) return 1;
        tell(w, fmi2Error, "fmi2Instantiate: the worker started for this instance did not accept it");
        return 0;
    }
    tell(w, fmi2Error, "fmi2Instantiate: no worker could be found or started (%d per runtime and host at most)",
         MAX_WORKERS);
    return 0;
}

static void release(Worker *w, int reaping)
{
    if (reaping && w->pid > 0 && w->control != NULL) reap(w, WORKER_EXIT_WAIT_MS);
    channel_close(&w->ch);
    if (w->control != NULL) munmap(w->control, WORKER_CONTROL_SIZE);
    int fds[] = {w->connection, w->output};
    for (size_t i = 0; i < sizeof fds / sizeof *fds; ++i)
        if (fds[i] >= 0) close(fds[i]);
    free_worker(w);
    close_ended_lifelines();
}
#endif

/* ---- one exchange --------------------------------------------------------------------------------- */

/* A changing call invalidates the cache; with `prefetch` the worker sends the listed values after it. */
static Writer begin(Worker *w, uint32_t op, int changes, int prefetch)
{
    if (changes) ++w->epoch;
    Writer out = {&w->ch, 0, 0};
    put_u32(&out, op);
    put_u32(&out, (uint32_t)prefetch);
    put_u32(&out, (uint32_t)w->list_changed);
    if (w->list_changed) put_array(&out, w->list, w->n_list, sizeof *w->list);
    return out;
}

/* Send the request, wait for the answer; its status (fmi2Fatal if the worker ended) and a reader after
 * it, for the operation's results. */
static fmi2Status exchange(Worker *w, Writer *out, Reader *in, const char *function)
{
    if (w->gone) return ended(w, function);
    if (out->failed) {
        tell(w, fmi2Error, "%s: out of memory for the request to the worker", function);
        return fmi2Error;
    }
    if (!worker_alive(w)) return ended(w, function);
    w->list_changed = 0;
    w->ch.head->length = out->pos;
    uint32_t asked = ++w->request;
    atomic_store(&w->ch.head->request, asked);
    channel_ring(&w->control->doorbell, &w->control->worker_sleeps, w->wake_worker);
    if (!channel_wait(&w->ch.head->response, asked - 1, &w->ch.head->client_sleeps, w->wake_client, SPIN_CALL_NS,
                      worker_alive, w)
        || !channel_sync(&w->ch) || atomic_load(&w->ch.head->response) != asked)
        return ended(w, function);
    *in = (Reader){w->ch.data, 0, w->ch.head->length, 0};
    return (fmi2Status)take_i32(in);
}

/* After the results: pass the messages logged during the call to the host's logger and take the
 * prefetched values. Returns the number of messages, or -1 if the answer was not complete. */
static int finish(Worker *w, Reader *in)
{
    uint32_t n = take_u32(in);
    for (uint32_t i = 0; i < n && !in->failed; ++i) {
        char category[256], message[16384];
        int32_t status = take_i32(in);
        take_string(in, category, sizeof category);
        take_string(in, message, sizeof message);
        if (!in->failed && w->callbacks != NULL && w->callbacks->logger != NULL)
            w->callbacks->logger(w->callbacks->componentEnvironment, w->name, (fmi2Status)status, category, message);
    }
    if (take_u32(in)) {
        uint32_t m;
        const double *values = take_array(in, &m, sizeof *values);
        if (values != NULL && m == w->n_list) {
            for (uint32_t i = 0; i < m; ++i) {
                memcpy(&w->value[w->list[i]], &values[i], sizeof(double));
                w->cached[w->list[i]] = w->epoch;
            }
        }
    }
    return in->failed ? -1 : (int)n;
}

static fmi2Status incomplete(Worker *w, const char *function)
{
    tell(w, fmi2Error, "%s: the worker's answer was incomplete", function);
    return fmi2Error;
}

/* A call whose only result is its status. */
static fmi2Status simple(Worker *w, uint32_t op, const char *function, int changes, int prefetch)
{
    Writer out = begin(w, op, changes, prefetch);
    Reader in;
    fmi2Status status = exchange(w, &out, &in, function);
    if (w->gone) return status;
    return finish(w, &in) < 0 ? incomplete(w, function) : status;
}

/* ---- the cache ------------------------------------------------------------------------------------ */

static int grow_slots(Worker *w, fmi2ValueReference vr)
{
    if (vr < w->n_slots) return 1;
    if (vr >= MAX_CACHED_REFERENCE) return 0;
    size_t n = w->n_slots ? w->n_slots : 256;
    while (n <= vr) n *= 2;
    double *value = realloc(w->value, n * sizeof *value);
    if (value != NULL) w->value = value;
    uint64_t *cached = realloc(w->cached, n * sizeof *cached);
    if (cached != NULL) w->cached = cached;
    unsigned char *listed = realloc(w->listed, n);
    if (listed != NULL) w->listed = listed;
    if (value == NULL || cached == NULL || listed == NULL) return 0;
    for (size_t i = w->n_slots; i < n; ++i) {
        cached[i] = w->epoch - 1;        /* not valid now */
        listed[i] = 0;
    }
    w->n_slots = n;
    return 1;
}

static void remember(Worker *w, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    for (size_t i = 0; i < nvr; ++i) {
        if (!grow_slots(w, vr[i])) continue;
        w->value[vr[i]] = value[i];
        w->cached[vr[i]] = w->epoch;
        if (w->listed[vr[i]]) continue;
        if (w->n_list == w->cap_list) {
            uint32_t cap = w->cap_list ? 2 * w->cap_list : 64;
            fmi2ValueReference *grown = realloc(w->list, cap * sizeof *grown);
            if (grown == NULL) continue;
            w->list = grown;
            w->cap_list = cap;
        }
        w->list[w->n_list++] = vr[i];
        w->listed[vr[i]] = 1;
        w->list_changed = 1;
    }
}

static int all_cached(const Worker *w, const fmi2ValueReference vr[], size_t nvr)
{
    for (size_t i = 0; i < nvr; ++i)
        if (vr[i] >= w->n_slots || w->cached[vr[i]] != w->epoch) return 0;
    return 1;
}

static void keep_strings(Worker *w, Reader *in, uint32_t n, fmi2String out[])
{
    for (size_t i = 0; i < w->n_strings; ++i) free(w->strings[i]);
    free(w->strings);
    w->strings = calloc(n > 0 ? n : 1, sizeof *w->strings);
    w->n_strings = w->strings != NULL ? n : 0;
    for (uint32_t i = 0; i < w->n_strings; ++i) {
        uint32_t length = take_u32(in);
        const char *text = take(in, length);
        w->strings[i] = text != NULL ? strndup(text, length) : NULL;
        out[i] = w->strings[i] != NULL ? w->strings[i] : "";
    }
}

/* ---- the FMI functions ---------------------------------------------------------------------------- */

/* fmi2FreeInstance of the worker's instance; 1 if the worker ends with it (its last instance). */
static int free_in_worker(Worker *w)
{
    Writer out = begin(w, OP_FREE_INSTANCE, 1, 0);
    Reader in;
    exchange(w, &out, &in, "fmi2FreeInstance");
    if (w->gone || finish(w, &in) < 0) return 0;
    return (int)take_u32(&in);
}

static fmi2Component worker_Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String location,
                                        const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                                        fmi2Boolean logging_on)
{
    (void)logging_on;                    /* the shim filters the messages; the worker logs everything */
    Worker *w = calloc(1, sizeof *w);
    char folder[3800];                   /* room for the file names after it in start_worker */
    if (w == NULL) return NULL;
#ifndef _WIN32
    w->ch.fd = w->connection = w->output = -1;
#endif
    w->callbacks = functions;
    w->name = strdup(name);
    if (w->name == NULL) {
        release(w, 0);
        return NULL;
    }
    if (!binary_folder(folder, sizeof folder)) {
        tell(w, fmi2Error, "fmi2Instantiate: the folder of the FMU's binary is unknown");
        release(w, 0);
        return NULL;
    }
    if (!open_channel(w)) {
        release(w, 0);
        return NULL;
    }
    w->ch.head->magic = CHANNEL_MAGIC;
    w->ch.head->version = CHANNEL_VERSION;
    atomic_store(&w->ch.head->size, CHANNEL_INITIAL_SIZE);
    if (!find_worker(w, folder)) {
        release(w, 0);
        return NULL;
    }
    Writer out = begin(w, OP_INSTANTIATE, 1, 0);
    put_string(&out, name);
    put_i32(&out, (int32_t)type);
    put_string(&out, guid);
    put_string(&out, location);
    put_i32(&out, visible);
    Reader in;
    fmi2Status status = exchange(w, &out, &in, "fmi2Instantiate");
    if (!w->gone && finish(w, &in) < 0) status = incomplete(w, "fmi2Instantiate");
    if (status > fmi2Warning) {
        release(w, !w->gone && free_in_worker(w));
        return NULL;
    }
    return w;
}

static void worker_FreeInstance(fmi2Component c)
{
    Worker *w = (Worker *)c;
    release(w, !w->gone && free_in_worker(w));
}

static fmi2Status worker_SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String categories[])
{
    (void)c, (void)on, (void)n, (void)categories;
    return fmi2OK;                       /* the shim keeps the host's choice and filters */
}

static fmi2Status worker_SetupExperiment(fmi2Component c, fmi2Boolean has_tolerance, fmi2Real tolerance,
                                         fmi2Real start, fmi2Boolean has_stop, fmi2Real stop)
{
    Worker *w = (Worker *)c;
    Writer out = begin(w, OP_SETUP_EXPERIMENT, 1, 1);
    put_i32(&out, has_tolerance);
    put_f64(&out, tolerance);
    put_f64(&out, start);
    put_i32(&out, has_stop);
    put_f64(&out, stop);
    Reader in;
    fmi2Status status = exchange(w, &out, &in, "fmi2SetupExperiment");
    if (w->gone) return status;
    return finish(w, &in) < 0 ? incomplete(w, "fmi2SetupExperiment") : status;
}

static fmi2Status worker_EnterInitializationMode(fmi2Component c)
{
    return simple((Worker *)c, OP_ENTER_INITIALIZATION_MODE, "fmi2EnterInitializationMode", 1, 1);
}

static fmi2Status worker_ExitInitializationMode(fmi2Component c)
{
    return simple((Worker *)c, OP_EXIT_INITIALIZATION_MODE, "fmi2ExitInitializationMode", 1, 1);
}

static fmi2Status worker_Terminate(fmi2Component c)
{
    return simple((Worker *)c, OP_TERMINATE, "fmi2Terminate", 1, 1);
}

static fmi2Status worker_Reset(fmi2Component c) { return simple((Worker *)c, OP_RESET, "fmi2Reset", 1, 1); }

static fmi2Status worker_CancelStep(fmi2Component c)
{
    return simple((Worker *)c, OP_CANCEL_STEP, "fmi2CancelStep", 1, 1);
}

static fmi2Status worker_DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_prior)
{
    Worker *w = (Worker *)c;
    Writer out = begin(w, OP_DO_STEP, 1, 1);
    put_f64(&out, t);
    put_f64(&out, h);
    put_i32(&out, no_prior);
    Reader in;
    fmi2Status status = exchange(w, &out, &in, "fmi2DoStep");
    if (w->gone) return status;
    return finish(w, &in) < 0 ? incomplete(w, "fmi2DoStep") : status;
}

static fmi2Status worker_GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    Worker *w = (Worker *)c;
    if (all_cached(w, vr, nvr)) {
        for (size_t i = 0; i < nvr; ++i) value[i] = w->value[vr[i]];
        return fmi2OK;
    }
    Writer out = begin(w, OP_GET_REAL, 0, 0);
    put_array(&out, vr, (uint32_t)nvr, sizeof *vr);
    Reader in;
    fmi2Status status = exchange(w, &out, &in, "fmi2GetReal");
    if (w->gone) return status;
    uint32_t n;
    const void *values = take_array(&in, &n, sizeof(fmi2Real));
    if (values != NULL && n == nvr && nvr > 0) memcpy(value, values, nvr * sizeof(fmi2Real));
    int logged = finish(w, &in);
    if (logged < 0 || n != nvr) return incomplete(w, "fmi2GetReal");
    if (status == fmi2OK && logged == 0) remember(w, vr, nvr, value);
    return status;
}

static fmi2Status get_values(Worker *w, uint32_t op, const char *function, const fmi2ValueReference vr[],
                             size_t nvr, void *value, size_t size)
{
    Writer out = begin(w, op, 0, 0);
    put_array(&out, vr, (uint32_t)nvr, sizeof *vr);
    Reader in;
    fmi2Status status = exchange(w, &out, &in, function);
    if (w->gone) return status;
    uint32_t n;
    const void *values = take_array(&in, &n, size);
    if (values != NULL && n == nvr && nvr > 0) memcpy(value, values, nvr * size);
    return finish(w, &in) < 0 || n != nvr ? incomplete(w, function) : status;
}

static fmi2Status worker_GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    return get_values((Worker *)c, OP_GET_INTEGER, "fmi2GetInteger", vr, nvr, value, sizeof *value);
}

static fmi2Status worker_GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    return get_values((Worker *)c, OP_GET_BOOLEAN, "fmi2GetBoolean", vr, nvr, value, sizeof *value);
}

static fmi2Status worker_GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    Worker *w = (Worker *)c;
    Writer out = begin(w, OP_GET_STRING, 0, 0);
    put_array(&out, vr, (uint32_t)nvr, sizeof *vr);
    Reader in;
    fmi2Status status = exchange(w, &out, &in, "fmi2GetString");
    if (w->gone) return status;
    uint32_t n = take_u32(&in);
    if (n != nvr) return incomplete(w, "fmi2GetString");
    keep_strings(w, &in, n, value);
    return finish(w, &in) < 0 ? incomplete(w, "fmi2GetString") : status;
}

static fmi2Status set_values(Worker *w, uint32_t op, const char *function, const fmi2ValueReference vr[],
                             size_t nvr, const void *value, size_t size)
{
    Writer out = begin(w, op, 1, 0);
    put_array(&out, vr, (uint32_t)nvr, sizeof *vr);
    put_array(&out, value, (uint32_t)nvr, size);
    Reader in;
    fmi2Status status = exchange(w, &out, &in, function);
    if (w->gone) return status;
    return finish(w, &in) < 0 ? incomplete(w, function) : status;
}

static fmi2Status worker_SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    return set_values((Worker *)c, OP_SET_REAL, "fmi2SetReal", vr, nvr, value, sizeof *value);
}

static fmi2Status worker_SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                    const fmi2Integer value[])
{
    return set_values((Worker *)c, OP_SET_INTEGER, "fmi2SetInteger", vr, nvr, value, sizeof *value);
}

static fmi2Status worker_SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                    const fmi2Boolean value[])
{
    return set_values((Worker *)c, OP_SET_BOOLEAN, "fmi2SetBoolean", vr, nvr, value, sizeof *value);
}

static fmi2Status worker_SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                   const fmi2String value[])
{
    Worker *w = (Worker *)c;
    Writer out = begin(w, OP_SET_STRING, 1, 0);
    put_array(&out, vr, (uint32_t)nvr, sizeof *vr);
    for (size_t i = 0; i < nvr; ++i) put_string(&out, value[i]);
    Reader in;
    fmi2Status status = exchange(w, &out, &in, "fmi2SetString");
    if (w->gone) return status;
    return finish(w, &in) < 0 ? incomplete(w, "fmi2SetString") : status;
}

/* A call that passes a state handle and returns a 64-bit value (a state handle or a size). */
static fmi2Status state_call(Worker *w, uint32_t op, const char *function, int changes, int has_state,
                             uint64_t state, uint64_t *result)
{
    Writer out = begin(w, op, changes, changes);
    if (has_state) put_u64(&out, state);
    Reader in;
    fmi2Status status = exchange(w, &out, &in, function);
    if (w->gone) return status;
    uint64_t value = result != NULL ? take_u64(&in) : 0;
    if (finish(w, &in) < 0) return incomplete(w, function);
    if (result != NULL) *result = value;
    return status;
}

static fmi2Status worker_GetFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    uint64_t handle = 0;
    fmi2Status status = state_call((Worker *)c, OP_GET_FMU_STATE, "fmi2GetFMUstate", 0, 0, 0, &handle);
    *state = (fmi2FMUstate)(uintptr_t)handle;
    return status;
}

static fmi2Status worker_SetFMUstate(fmi2Component c, fmi2FMUstate state)
{
    return state_call((Worker *)c, OP_SET_FMU_STATE, "fmi2SetFMUstate", 1, 1, (uintptr_t)state, NULL);
}

static fmi2Status worker_FreeFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    fmi2Status status = state_call((Worker *)c, OP_FREE_FMU_STATE, "fmi2FreeFMUstate", 0, 1, (uintptr_t)*state, NULL);
    *state = NULL;
    return status;
}

static fmi2Status worker_SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size)
{
    uint64_t n = 0;
    fmi2Status status = state_call((Worker *)c, OP_SERIALIZED_FMU_STATE_SIZE, "fmi2SerializedFMUstateSize", 0, 1,
                                   (uintptr_t)state, &n);
    *size = (size_t)n;
    return status;
}

static fmi2Status worker_SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size)
{
    Worker *w = (Worker *)c;
    Writer out = begin(w, OP_SERIALIZE_FMU_STATE, 0, 0);
    put_u64(&out, (uintptr_t)state);
    put_u64(&out, size);
    Reader in;
    fmi2Status status = exchange(w, &out, &in, "fmi2SerializeFMUstate");
    if (w->gone) return status;
    uint32_t n;
    const void *data = take_array(&in, &n, 1);
    if (data != NULL && n == size && n > 0) memcpy(bytes, data, n);
    return finish(w, &in) < 0 || n != size ? incomplete(w, "fmi2SerializeFMUstate") : status;
}

static fmi2Status worker_DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size,
                                             fmi2FMUstate *state)
{
    Worker *w = (Worker *)c;
    Writer out = begin(w, OP_DESERIALIZE_FMU_STATE, 0, 0);
    put_array(&out, bytes, (uint32_t)size, 1);
    Reader in;
    fmi2Status status = exchange(w, &out, &in, "fmi2DeSerializeFMUstate");
    if (w->gone) return status;
    uint64_t handle = take_u64(&in);
    if (finish(w, &in) < 0) return incomplete(w, "fmi2DeSerializeFMUstate");
    *state = (fmi2FMUstate)(uintptr_t)handle;
    return status;
}

static fmi2Status worker_GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference unknown[],
                                                  size_t n_unknown, const fmi2ValueReference known[],
                                                  size_t n_known, const fmi2Real dv_known[], fmi2Real dv_unknown[])
{
    Worker *w = (Worker *)c;
    Writer out = begin(w, OP_GET_DIRECTIONAL_DERIVATIVE, 0, 0);
    put_array(&out, unknown, (uint32_t)n_unknown, sizeof *unknown);
    put_array(&out, known, (uint32_t)n_known, sizeof *known);
    put_array(&out, dv_known, (uint32_t)n_known, sizeof *dv_known);
    Reader in;
    fmi2Status status = exchange(w, &out, &in, "fmi2GetDirectionalDerivative");
    if (w->gone) return status;
    uint32_t n;
    const void *values = take_array(&in, &n, sizeof(fmi2Real));
    if (values != NULL && n == n_unknown && n > 0) memcpy(dv_unknown, values, n * sizeof(fmi2Real));
    return finish(w, &in) < 0 || n != n_unknown ? incomplete(w, "fmi2GetDirectionalDerivative") : status;
}

static fmi2Status worker_SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                                 const fmi2Integer order[], const fmi2Real value[])
{
    Worker *w = (Worker *)c;
    Writer out = begin(w, OP_SET_REAL_INPUT_DERIVATIVES, 1, 0);
    put_array(&out, vr, (uint32_t)nvr, sizeof *vr);
    put_array(&out, order, (uint32_t)nvr, sizeof *order);
    put_array(&out, value, (uint32_t)nvr, sizeof *value);
    Reader in;
    fmi2Status status = exchange(w, &out, &in, "fmi2SetRealInputDerivatives");
    if (w->gone) return status;
    return finish(w, &in) < 0 ? incomplete(w, "fmi2SetRealInputDerivatives") : status;
}

static fmi2Status worker_GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                                  const fmi2Integer order[], fmi2Real value[])
{
    Worker *w = (Worker *)c;
    Writer out = begin(w, OP_GET_REAL_OUTPUT_DERIVATIVES, 0, 0);
    put_array(&out, vr, (uint32_t)nvr, sizeof *vr);
    put_array(&out, order, (uint32_t)nvr, sizeof *order);
    Reader in;
    fmi2Status status = exchange(w, &out, &in, "fmi2GetRealOutputDerivatives");
    if (w->gone) return status;
    uint32_t n;
    const void *values = take_array(&in, &n, sizeof(fmi2Real));
    if (values != NULL && n == nvr && n > 0) memcpy(value, values, n * sizeof(fmi2Real));
    return finish(w, &in) < 0 || n != nvr ? incomplete(w, "fmi2GetRealOutputDerivatives") : status;
}

/* fmi2GetStatus and the typed variants: one value of the kind asked for. */
static fmi2Status status_call(Worker *w, uint32_t op, const char *function, fmi2StatusKind kind, void *value)
{
    Writer out = begin(w, op, 0, 0);
    put_i32(&out, (int32_t)kind);
    Reader in;
    fmi2Status status = exchange(w, &out, &in, function);
    if (w->gone) return status;
    if (op == OP_GET_REAL_STATUS) *(fmi2Real *)value = take_f64(&in);
    else if (op == OP_GET_STRING_STATUS) keep_strings(w, &in, 1, (fmi2String *)value);
    else *(fmi2Integer *)value = take_i32(&in);
    return finish(w, &in) < 0 ? incomplete(w, function) : status;
}

static fmi2Status worker_GetStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Status *value)
{
    return status_call((Worker *)c, OP_GET_STATUS, "fmi2GetStatus", kind, value);
}

static fmi2Status worker_GetRealStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Real *value)
{
    return status_call((Worker *)c, OP_GET_REAL_STATUS, "fmi2GetRealStatus", kind, value);
}

static fmi2Status worker_GetIntegerStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Integer *value)
{
    return status_call((Worker *)c, OP_GET_INTEGER_STATUS, "fmi2GetIntegerStatus", kind, value);
}

static fmi2Status worker_GetBooleanStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Boolean *value)
{
    return status_call((Worker *)c, OP_GET_BOOLEAN_STATUS, "fmi2GetBooleanStatus", kind, value);
}

static fmi2Status worker_GetStringStatus(fmi2Component c, const fmi2StatusKind kind, fmi2String *value)
{
    return status_call((Worker *)c, OP_GET_STRING_STATUS, "fmi2GetStringStatus", kind, value);
}

/* The table fmi_shim.c forwards to. */
static const Fmi2Table worker_table = {
#define FMI2_WORKER_ENTRY(name) worker_##name,
    FMI2_CO_SIMULATION_FUNCTIONS(FMI2_WORKER_ENTRY)
#undef FMI2_WORKER_ENTRY
};
