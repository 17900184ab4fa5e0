/* The channels between a standalone FMU's binary in the host process (worker_client.c) and a worker
 * process (fmi_worker.c), and how a client finds a worker.
 *
 * One worker serves the instances of the standalone FMUs of one host process that can share a Python
 * interpreter (the same runtime, the same code of every Python package they both carry), at most one
 * instance of each FMU: the structure and aero units of a scene run in one worker, as they would in one
 * Python process, and two instances of one FMU in two workers, so that a host can step them in parallel.
 * The first client starts the worker with a listening Unix socket in the abstract namespace, named by the
 * host's pid, the runtime's key and a number (`worker_address`); every client, the first too, connects to
 * it and joins (`JoinRequest`, its channel's file passed along), and the worker accepts or refuses
 * (`JoinReply`, with its control page and output file when it accepts). The connection stays open: it
 * hangs up when the worker ends, in whatever way, which is how a client sees it end.
 *
 * Per instance, a channel (`ChannelHeader` and its data area, a shared memory file): the client writes a
 * request (an operation code and its arguments, docs in the two .c files) into the data area, increments
 * `request` and rings the worker's doorbell (`WorkerControl`); the worker carries it out, writes the
 * response over the same area, sets `response` to `request` and wakes the client. Both wait by spinning
 * first: waking a process that sleeps on an idle CPU costs tens of microseconds in a virtual machine (the
 * hypervisor must wake that CPU), several times the cost of a small step's exchange, so a waiting side
 * that may run on several CPUs spins (pause, then sched_yield, which gives the CPU to any other runnable
 * process) before it sleeps on a futex: a worker waiting for the next request up to SPIN_YIELD_NS, a client
 * waiting for an answer (it has nothing else to do) up to SPIN_CALL_NS; a coupled run keeps both sides
 * within those windows. Confined to one CPU, it sleeps at once: the other side cannot run while it spins.
 *
 * The data area grows when a message needs more (a serialized FMU state): the writer extends the file
 * and its own mapping and records the new size in the header; the reader maps the file again when the
 * recorded size exceeds its mapping. Values are written in the host's byte order; arrays of 8-byte
 * values start at 8-byte offsets so that a pointer into the area can be handed to an FMI function.
 *
 * On Windows (binaries/win64, compiled with mingw-w64) every instance has a worker of its own, started by
 * its client with the handles on its command line (worker_client_win.c, fmi_worker_win.c): no joining, so
 * nothing below about sockets applies. The channel and the control page are pagefile-backed sections; the
 * channel's section reserves CHANNEL_MAX_SIZE and its pages are committed as it grows (the size protocol is
 * the same). A sleeping side waits on an auto-reset event (`ChannelEvent`) instead of a futex, with the same
 * "sleeps" flags: the other side sets the event only when the flag says it sleeps.
 */
#ifndef WINGSIM_WORKER_CHANNEL_H
#define WINGSIM_WORKER_CHANNEL_H

#include <errno.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#ifdef _WIN32
#include <windows.h>
typedef HANDLE ChannelEvent;               /* the auto-reset event a sleeping side waits on */
#define NO_EVENT NULL
#else
/* the including file defines _GNU_SOURCE before its first system header (syscall, sched_yield) */
#include <linux/futex.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>
typedef int ChannelEvent;                  /* unused: a sleeping side waits on a futex, the word itself */
#define NO_EVENT 0
#endif

#define CHANNEL_MAGIC 0x57494e47u  /* "WING" */
#define CHANNEL_VERSION 2u
#define CHANNEL_DATA_OFFSET 256    /* after the header, on a cache line of its own */
#define CHANNEL_INITIAL_SIZE (1u << 20)
#define SPIN_PAUSE_NS 20000L       /* busy-wait with pause for 20 us, */
#define SPIN_YIELD_NS 2000000L     /* then yield the CPU in a loop up to 2 ms (a worker), */
#define SPIN_CALL_NS 20000000L     /* or 20 ms (a client, whose call cannot return sooner), then sleep */
#define SLEEP_CHECK_NS 20000000L   /* a sleeping client wakes every 20 ms to see whether the worker lives */
#define CHANNEL_MAX_SIZE ((size_t)1 << 30)   /* Windows: the address space a channel reserves */

/* Operations: one per FMI 2.0 co-simulation function the client forwards. */
enum {
    OP_INSTANTIATE = 1, OP_FREE_INSTANCE, OP_SETUP_EXPERIMENT, OP_ENTER_INITIALIZATION_MODE,
    OP_EXIT_INITIALIZATION_MODE, OP_TERMINATE, OP_RESET, OP_GET_REAL, OP_GET_INTEGER, OP_GET_BOOLEAN,
    OP_GET_STRING, OP_SET_REAL, OP_SET_INTEGER, OP_SET_BOOLEAN, OP_SET_STRING, OP_GET_FMU_STATE,
    OP_SET_FMU_STATE, OP_FREE_FMU_STATE, OP_SERIALIZED_FMU_STATE_SIZE, OP_SERIALIZE_FMU_STATE,
    OP_DESERIALIZE_FMU_STATE, OP_GET_DIRECTIONAL_DERIVATIVE, OP_SET_REAL_INPUT_DERIVATIVES,
    OP_GET_REAL_OUTPUT_DERIVATIVES, OP_DO_STEP, OP_CANCEL_STEP, OP_GET_STATUS, OP_GET_REAL_STATUS,
    OP_GET_INTEGER_STATUS, OP_GET_BOOLEAN_STATUS, OP_GET_STRING_STATUS, OP_COUNT
};

typedef struct {
    uint32_t magic, version;
    _Atomic uint64_t size;                 /* bytes of the file (header included) */
    uint64_t length;                       /* bytes of the message in the data area */
    char pad1[64 - 24];
    _Atomic uint32_t request;              /* written by the client: the number of its latest request */
    char pad2[64 - 4];
    _Atomic uint32_t response;             /* written by the worker: the request it has answered */
    _Atomic uint32_t client_sleeps;        /* the client sleeps on `response` */
} ChannelHeader;

_Static_assert(sizeof(ChannelHeader) <= CHANNEL_DATA_OFFSET, "the header overlaps the data");

/* The worker's control page, shared with every client: one doorbell for all its channels. */
typedef struct {
    uint32_t magic, version;
    _Atomic int32_t exit_status;           /* the worker's wait status, once a client has reaped it; else -1 */
    char pad1[64 - 12];
    _Atomic uint32_t doorbell;             /* incremented by a client after each request */
    _Atomic uint32_t worker_sleeps;        /* the worker sleeps on `doorbell` */
} WorkerControl;

#define WORKER_CONTROL_SIZE 4096
#define GUID_SIZE 128
#define PACKAGES_SIZE 2048

#ifndef _WIN32

/* A client's request to be served (its channel's file passed with it, SCM_RIGHTS). `packages` names the
 * Python code the FMU brings, "name=digest;..." (the slave script, the packages of its resources): a
 * worker that has loaded a module of the same name from other code refuses, as it does a second instance
 * of an FMU (`guid`) and any join once it has begun to end. */
typedef struct {
    uint32_t magic, version;
    char guid[GUID_SIZE];
    char packages[PACKAGES_SIZE];
} JoinRequest;

/* The worker's answer (with its control page and output file when it accepts, SCM_RIGHTS). */
typedef struct {
    int32_t accepted;
    int32_t pid;
    char reason[256];                      /* why it refused */
} JoinReply;

/* The abstract socket address of worker `number` of runtime `key` for host process `host`. */
__attribute__((unused)) static socklen_t worker_address(struct sockaddr_un *address, long host, const char *key, int number)
{
    memset(address, 0, sizeof *address);
    address->sun_family = AF_UNIX;
    int n = snprintf(address->sun_path + 1, sizeof address->sun_path - 1, "wingsim/%ld/%s/%d", host, key, number);
    return (socklen_t)(offsetof(struct sockaddr_un, sun_path) + 1 + (size_t)n);
}

/* Send `size` bytes and the descriptors `fds` (n_fds of them) on the socket; 0 on failure. */
static int send_with_fds(int socket, const void *data, size_t size, const int *fds, int n_fds)
{
    char control[CMSG_SPACE(4 * sizeof(int))];
    struct iovec part = {(void *)data, size};
    struct msghdr message = {NULL, 0, &part, 1, n_fds > 0 ? control : NULL, n_fds > 0 ? CMSG_SPACE(n_fds * sizeof(int)) : 0, 0};
    if (n_fds > 0) {
        memset(control, 0, sizeof control);
        struct cmsghdr *header = CMSG_FIRSTHDR(&message);
        header->cmsg_level = SOL_SOCKET;
        header->cmsg_type = SCM_RIGHTS;
        header->cmsg_len = CMSG_LEN(n_fds * sizeof(int));
        memcpy(CMSG_DATA(header), fds, n_fds * sizeof(int));
    }
    ssize_t sent;
    while ((sent = sendmsg(socket, &message, MSG_NOSIGNAL)) < 0 && errno == EINTR) {
    }
    return sent == (ssize_t)size;
}

/* Receive exactly `size` bytes and up to `max_fds` descriptors (close-on-exec; *n_fds set); 0 on failure. */
static int receive_with_fds(int socket, void *data, size_t size, int *fds, int max_fds, int *n_fds)
{
    char control[CMSG_SPACE(4 * sizeof(int))];
    struct iovec part = {data, size};
    struct msghdr message = {NULL, 0, &part, 1, control, sizeof control, 0};
    ssize_t got;
    *n_fds = 0;
    while ((got = recvmsg(socket, &message, MSG_WAITALL | MSG_CMSG_CLOEXEC)) < 0 && errno == EINTR) {
    }
    for (struct cmsghdr *h = CMSG_FIRSTHDR(&message); h != NULL; h = CMSG_NXTHDR(&message, h)) {
        if (h->cmsg_level != SOL_SOCKET || h->cmsg_type != SCM_RIGHTS) continue;
        int count = (int)((h->cmsg_len - CMSG_LEN(0)) / sizeof(int));
        for (int i = 0; i < count; ++i) {
            int fd;
            memcpy(&fd, CMSG_DATA(h) + i * sizeof(int), sizeof fd);
            if (*n_fds < max_fds) fds[(*n_fds)++] = fd;
            else close(fd);
        }
    }
    return got == (ssize_t)size;
}
#endif

typedef struct {
#ifdef _WIN32
    HANDLE section;                        /* the pagefile-backed section */
#else
    int fd;                                /* the shared memory file */
#endif
    size_t mapped;                         /* bytes of this side's mapping (Windows: committed in its view) */
    ChannelHeader *head;
    unsigned char *data;                   /* head + CHANNEL_DATA_OFFSET */
} Channel;

#ifdef _WIN32
static long long channel_now_ns(void)
{
    static LARGE_INTEGER frequency;
    LARGE_INTEGER t;
    if (frequency.QuadPart == 0) QueryPerformanceFrequency(&frequency);
    QueryPerformanceCounter(&t);
    return (long long)((double)t.QuadPart * 1e9 / (double)frequency.QuadPart);
}

/* Map the whole section once (address space only), then commit its first `size` bytes in this view: the
 * other side's commits are its own, each view commits what it touches. */
static int channel_map(Channel *ch, size_t size)
{
    if (ch->head == NULL) {
        void *p = MapViewOfFile(ch->section, FILE_MAP_READ | FILE_MAP_WRITE, 0, 0, CHANNEL_MAX_SIZE);
        if (p == NULL) return 0;
        ch->head = (ChannelHeader *)p;
        ch->data = (unsigned char *)p + CHANNEL_DATA_OFFSET;
    }
    if (size > CHANNEL_MAX_SIZE || VirtualAlloc(ch->head, size, MEM_COMMIT, PAGE_READWRITE) == NULL) return 0;
    ch->mapped = size;
    return 1;
}

static int channel_grow(Channel *ch, size_t size) { return channel_map(ch, size); }

static void channel_close(Channel *ch)
{
    if (ch->head != NULL) UnmapViewOfFile(ch->head);
    if (ch->section != NULL) CloseHandle(ch->section);
    ch->head = NULL;
    ch->section = NULL;
}

static void channel_yield(void) { SwitchToThread(); }

/* Asked once: under Wine every GetProcessAffinityMask is a round trip to its server (tens of
 * microseconds), which asked before every wait would cost more than the exchange it decides about. */
static int channel_several_cpus(void)
{
    static int known = -1;
    if (known < 0) {
        DWORD_PTR process, system;
        known = !GetProcessAffinityMask(GetCurrentProcess(), &process, &system) || (process & (process - 1)) != 0;
    }
    return known;
}

static void channel_sleep(_Atomic uint32_t *word, uint32_t value, ChannelEvent event, int bounded)
{
    (void)word, (void)value;           /* a wake-up that came before the wait left the event set */
    WaitForSingleObject(event, bounded ? (DWORD)(SLEEP_CHECK_NS / 1000000) : INFINITE);
}

static void channel_wake(_Atomic uint32_t *word, ChannelEvent event)
{
    (void)word;
    SetEvent(event);
}
#else
static long channel_now_ns(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (long)t.tv_sec * 1000000000L + t.tv_nsec;
}

static int channel_map(Channel *ch, size_t size)
{
    void *p = mmap(NULL, size, PROT_READ | PROT_WRITE, MAP_SHARED, ch->fd, 0);
    if (p == MAP_FAILED) return 0;
    if (ch->head != NULL) munmap(ch->head, ch->mapped);
    ch->head = (ChannelHeader *)p;
    ch->data = (unsigned char *)p + CHANNEL_DATA_OFFSET;
    ch->mapped = size;
    return 1;
}

static int channel_grow(Channel *ch, size_t size)
{
    return ftruncate(ch->fd, (off_t)size) == 0 && channel_map(ch, size);
}

static void channel_close(Channel *ch)
{
    if (ch->head != NULL) munmap(ch->head, ch->mapped);
    if (ch->fd >= 0) close(ch->fd);
    ch->head = NULL;
    ch->fd = -1;
}

static void channel_yield(void) { sched_yield(); }

/* Whether this thread may run on more than one CPU: spinning only helps when the other side runs on
 * another CPU at the same time; on one CPU it only delays the other side. */
static int channel_several_cpus(void)
{
    cpu_set_t cpus;
    return sched_getaffinity(0, sizeof cpus, &cpus) != 0 || CPU_COUNT(&cpus) > 1;
}

/* Sleep while `*word` is `value`: up to SLEEP_CHECK_NS when `bounded`. */
static void channel_sleep(_Atomic uint32_t *word, uint32_t value, ChannelEvent event, int bounded)
{
    (void)event;
    struct timespec timeout = {0, SLEEP_CHECK_NS};
    syscall(SYS_futex, (uint32_t *)word, FUTEX_WAIT, value, bounded ? &timeout : NULL, NULL, 0);
}

static void channel_wake(_Atomic uint32_t *word, ChannelEvent event)
{
    (void)event;
    syscall(SYS_futex, (uint32_t *)word, FUTEX_WAKE, 1, NULL, NULL, 0);
}
#endif

/* Map the file again if the other side has grown it. */
static int channel_sync(Channel *ch)
{
    size_t size = (size_t)atomic_load(&ch->head->size);
    return size <= ch->mapped || channel_map(ch, size);
}

/* Room for `bytes` bytes of data: grows the file (doubling) when needed. */
static int channel_reserve(Channel *ch, size_t bytes)
{
    if (!channel_sync(ch)) return 0;
    if (CHANNEL_DATA_OFFSET + bytes <= ch->mapped) return 1;
    size_t size = ch->mapped;
    while (CHANNEL_DATA_OFFSET + bytes > size) size *= 2;
    if (!channel_grow(ch, size)) return 0;
    atomic_store(&ch->head->size, size);
    return 1;
}

static void channel_pause(void)
{
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#elif defined(__aarch64__)
    __asm__ __volatile__("yield");
#endif
}

/* Wait until `*word` is not `value`, spinning up to `spin_ns`, then sleeping (on `event` on Windows).
 * `alive(arg)` (may be NULL) is asked about every millisecond and when a sleep times out; it returns 0 when the other side is
 * gone, and so does channel_wait. */
static int channel_wait(_Atomic uint32_t *word, uint32_t value, _Atomic uint32_t *sleeps, ChannelEvent event,
                        long long spin_ns, int (*alive)(void *), void *arg)
{
    if (atomic_load_explicit(word, memory_order_acquire) != value) return 1;
    long long start = channel_now_ns(), checked = start;
    for (unsigned k = 1, spin = channel_several_cpus(); spin; ++k) {
        if (atomic_load_explicit(word, memory_order_acquire) != value) return 1;
        if (k % 64 != 0) {
            channel_pause();
            continue;
        }
        long long now = channel_now_ns();
        if (alive != NULL && now - checked > 1000000L) {
            if (!alive(arg)) return 0;
            checked = now;
        }
        if (now - start < SPIN_PAUSE_NS) continue;
        if (now - start < spin_ns) {
            channel_yield();
            continue;
        }
        break;
    }
    for (;;) {
        atomic_store(sleeps, 1);
        if (atomic_load(word) != value) break;
        channel_sleep(word, value, event, alive != NULL);
        atomic_store(sleeps, 0);
        if (atomic_load(word) != value) break;
        if (alive != NULL && !alive(arg)) return 0;
    }
    atomic_store(sleeps, 0);
    atomic_thread_fence(memory_order_acquire);
    return 1;
}

/* Set `*word` to `value` and wake the other side if it sleeps on it (on `event`, Windows). */
__attribute__((unused)) static void channel_signal(_Atomic uint32_t *word, uint32_t value, _Atomic uint32_t *sleeps, ChannelEvent event)
{
    atomic_store(word, value);
    if (atomic_load(sleeps)) channel_wake(word, event);
}

/* Ring a doorbell that several clients share: an increment, never lost to another client's (a plain store
 * of the value read plus one could be, and the worker would sleep through a request). */
static void channel_ring(_Atomic uint32_t *doorbell, _Atomic uint32_t *sleeps, ChannelEvent event)
{
    atomic_fetch_add(doorbell, 1);
    if (atomic_load(sleeps)) channel_wake(doorbell, event);
}

/* ---- messages: a writer appends to the data area, a reader takes from it in the same order ---- */

typedef struct {
    Channel *ch;
    size_t pos;
    int failed;                            /* out of memory: the message is incomplete */
} Writer;

typedef struct {
    const unsigned char *data;
    size_t pos, end;
    int failed;                            /* the message ended early: it is not what was expected */
} Reader;

static void put(Writer *w, const void *p, size_t n)
{
    if (w->failed || !channel_reserve(w->ch, w->pos + n)) {
        w->failed = 1;
        return;
    }
    if (n > 0) memcpy(w->ch->data + w->pos, p, n);
    w->pos += n;
}

static void put_u32(Writer *w, uint32_t v) { put(w, &v, sizeof v); }
static void put_i32(Writer *w, int32_t v) { put(w, &v, sizeof v); }
static void put_u64(Writer *w, uint64_t v) { put(w, &v, sizeof v); }
static void put_f64(Writer *w, double v) { put(w, &v, sizeof v); }

/* An array of `n` items of `size` bytes, starting at an 8-byte offset, after its count. */
static void put_array(Writer *w, const void *p, uint32_t n, size_t size)
{
    static const unsigned char zeros[8] = {0};
    put_u32(w, n);
    put(w, zeros, (8 - w->pos % 8) % 8);
    put(w, p, (size_t)n * size);
}

static void put_string(Writer *w, const char *s)
{
    uint32_t n = s != NULL ? (uint32_t)strlen(s) : 0;
    put_u32(w, n);
    put(w, s, n);
}

static const void *take(Reader *r, size_t n)
{
    if (r->failed || n > r->end - r->pos) {
        r->failed = 1;
        return NULL;
    }
    const void *p = r->data + r->pos;
    r->pos += n;
    return p;
}

static uint32_t take_u32(Reader *r)
{
    uint32_t v = 0;
    const void *p = take(r, sizeof v);
    if (p != NULL) memcpy(&v, p, sizeof v);
    return v;
}

static int32_t take_i32(Reader *r)
{
    int32_t v = 0;
    const void *p = take(r, sizeof v);
    if (p != NULL) memcpy(&v, p, sizeof v);
    return v;
}

static uint64_t take_u64(Reader *r)
{
    uint64_t v = 0;
    const void *p = take(r, sizeof v);
    if (p != NULL) memcpy(&v, p, sizeof v);
    return v;
}

static double take_f64(Reader *r)
{
    double v = 0.0;
    const void *p = take(r, sizeof v);
    if (p != NULL) memcpy(&v, p, sizeof v);
    return v;
}

/* An array written by put_array: its items in place (8-byte aligned), its count in *n. */
static const void *take_array(Reader *r, uint32_t *n, size_t size)
{
    *n = take_u32(r);
    take(r, (8 - r->pos % 8) % 8);
    if (r->failed || (size > 0 && *n > (r->end - r->pos) / size)) {
        r->failed = 1;
        *n = 0;
        return NULL;
    }
    return take(r, (size_t)*n * size);
}

/* A string written by put_string, copied NUL-terminated into `out` (`size` bytes, truncated). */
static void take_string(Reader *r, char *out, size_t size)
{
    uint32_t n = take_u32(r);
    const char *p = take(r, n);
    size_t k = p == NULL ? 0 : (n < size ? n : size - 1);
    if (k > 0) memcpy(out, p, k);
    if (size > 0) out[k] = '\0';
}

#endif
