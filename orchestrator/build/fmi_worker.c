/* A worker process of standalone wingsim FMUs: the units' Python, started from the runtime the FMUs
 * carry, serving the FMI calls of the instances whose binaries in the host process joined it
 * (worker_client.c, worker_channel.h: at most one instance of each FMU, all of FMUs that can share an
 * interpreter).
 *
 * Started by the first of those clients as
 *     <binaries>/<id>_worker <pythonfmu binary> <runtime folder>
 * with an empty environment but for the WINGSIM_* variables, one BLAS thread and LD_LIBRARY_PATH (the
 * runtime's library folder, for the extension modules' own needs), in a process group of its own (a
 * terminal's Ctrl-C reaches the host, not the worker), and these descriptors:
 *     0  /dev/null        1, 2  a file the clients read when the worker fails (its output)
 *     3  lifeline: the read end of a pipe whose write end only the host holds; when the host process
 *        ends in whatever way (exit, crash, SIGKILL) the read returns and the worker exits at once
 *     4  its control page (WorkerControl: the doorbell every client rings after a request)
 *     5  the listening socket on which clients join (JoinRequest, each with its channel's file)
 * It links the runtime's libpython (RPATH $ORIGIN/runtime/lib), starts it isolated (no environment
 * variable, no site, no user folder, no signal handler: the module search path is the runtime's
 * standard library, its extension modules and its site-packages), loads pythonfmu's binary, which
 * imports each slave from its FMU's resources, and forwards each request to it: a unit behaves as the
 * ordinary FMU does, in a Python that nothing in the host can change. Two threads: the main one serves
 * the requests of every instance, one at a time (Python's); the door thread accepts joins, sees the
 * lifeline close and a client's connection hang up.
 *
 * A request (after the op code): u32 prefetch (1: after the call, return the values of the prefetch
 * list), u32 has_list (1: a new prefetch list of Real value references follows, as an array), then the
 * operation's arguments. A response: i32 status, the operation's results, the messages logged during
 * the call (u32 count, then i32 status, string category, string message each), then u32 valid and the
 * prefetched values as an array (valid 0 when the prefetch was not asked for, or logged anything or
 * returned anything but fmi2OK: the client then asks again when the host reads), then, for
 * OP_FREE_INSTANCE, u32 ending (1: it was the last instance; the worker refuses joins from then on and
 * exits after the answer). If Python or pythonfmu's binary cannot be loaded, every request is answered
 * with fmi2Error and the reason logged.
 *
 * With WINGSIM_WORKER_TRACE=FILE in the host's environment, the worker appends one line per request to
 * FILE: its pid, the operation's number (worker_channel.h) and when it began and ended serving it
 * (CLOCK_MONOTONIC, ns; one clock for every process of the machine): a timeline of the units' calls.
 *
 * On Windows (binaries/win64) a worker serves one instance, whose client started it (worker_client_win.c);
 * fmi_worker_win.c, included in place of the Linux section at the end, starts it. Requests are read and
 * answered by the same code. There is no trace there.
 */
#define _GNU_SOURCE
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifndef _WIN32
#include <dirent.h>
#include <fcntl.h>
#include <poll.h>
#include <sys/stat.h>
#endif

#include "fmi2_table.h"
#include "native_platform.h"
#include "worker_channel.h"

#define AS_TEXT(x) #x
#define NUMBER_TEXT(x) AS_TEXT(x)
#define STDLIB "lib/python" NUMBER_TEXT(PY_MAJOR_VERSION) "." NUMBER_TEXT(PY_MINOR_VERSION)
#define LIFELINE_FD 3
#define CONTROL_FD 4
#define LISTEN_FD 5
#define MESSAGE_SIZE 8192
#define PATH_SIZE 4096
#define MAX_SLOTS 32

/* ---- messages logged during the current call ---------------------------------------------------- */

typedef struct {
    int32_t status;
    char *category, *message;
} Record;

static Record *records = NULL;
static size_t n_records = 0, cap_records = 0;
static int capturing_prefetch = 0;     /* the prefetch's own messages go to `prefetch_logged` */
static int prefetch_logged = 0;

static void add_record(int32_t status, const char *category, const char *message)
{
    if (capturing_prefetch) {
        prefetch_logged = 1;
        return;
    }
    if (n_records == cap_records) {
        size_t cap = cap_records ? 2 * cap_records : 16;
        Record *grown = realloc(records, cap * sizeof *grown);
        if (grown == NULL) return;
        records = grown;
        cap_records = cap;
    }
    Record r = {status, strdup(category != NULL ? category : ""), strdup(message != NULL ? message : "")};
    if (r.category == NULL || r.message == NULL) {
        free(r.category);
        free(r.message);
        return;
    }
    records[n_records++] = r;
}

static void clear_records(void)
{
    for (size_t i = 0; i < n_records; ++i) {
        free(records[i].category);
        free(records[i].message);
    }
    n_records = 0;
}

/* pythonfmu passes its message as a printf format without arguments: it is kept as such (the host's
 * logger gets it as its format, as from the ordinary FMU). */
static void worker_logger(fmi2ComponentEnvironment env, fmi2String instance_name, fmi2Status status,
                          fmi2String category, fmi2String message, ...)
{
    (void)env;
    (void)instance_name;
    add_record((int32_t)status, category, message);
}

static void log_error(const char *format, ...)
{
    char text[MESSAGE_SIZE], escaped[2 * MESSAGE_SIZE];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    size_t k = 0;                     /* a printf format for the host: '%' doubled */
    for (const char *p = text; *p != '\0' && k + 2 < sizeof escaped; ++p) {
        if (*p == '%') escaped[k++] = '%';
        escaped[k++] = *p;
    }
    escaped[k] = '\0';
    add_record(fmi2Error, "logStatusError", escaped);
}

/* ---- Python and pythonfmu's binary ---------------------------------------------------------------- */

#ifdef _WIN32
/* python311.dll, python311.zip (the standard library), its extension modules, site-packages */
#define PATH_SEPARATOR "\\"
static const char *const SEARCH_PATH[] = {"python" NUMBER_TEXT(PY_MAJOR_VERSION) NUMBER_TEXT(PY_MINOR_VERSION) ".zip",
                                          "", "site-packages"};
#else
#define PATH_SEPARATOR "/"
static const char *const SEARCH_PATH[] = {STDLIB, STDLIB "/lib-dynload", "site-packages"};
#endif

static Fmi2Table fmi;

static char startup_error[MESSAGE_SIZE];

#ifdef _WIN32
#include "python_win.h"   /* the Python functions below, looked up in the runtime's python3X.dll */
#endif

static int config_failed(PyStatus status, const char *step)
{
    if (!PyStatus_Exception(status)) return 0;
    snprintf(startup_error, sizeof startup_error, "starting the FMU's Python failed in %s: %s",
             status.func != NULL ? status.func : step, status.err_msg != NULL ? status.err_msg : "it asked to exit");
    return 1;
}

static PyStatus append_path(PyConfig *config, const char *runtime, const char *sub)
{
    char path[PATH_SIZE];
    snprintf(path, sizeof path, "%s%s%s", runtime, sub[0] != '\0' ? PATH_SEPARATOR : "", sub);
    wchar_t *wide = Py_DecodeLocale(path, NULL);
    if (wide == NULL) return PyStatus_NoMemory();
    PyStatus status = PyWideStringList_Append(&config->module_search_paths, wide);
    PyMem_RawFree(wide);
    return status;
}

/* Start the runtime's Python, isolated from everything outside `runtime`. */
static int start_python(const char *program, const char *runtime)
{
#ifdef _WIN32
    if (!load_python(runtime)) return 0;
#endif
    PyPreConfig preconfig;
    PyPreConfig_InitIsolatedConfig(&preconfig);
    preconfig.utf8_mode = 1;
    if (config_failed(Py_PreInitialize(&preconfig), "Py_PreInitialize")) return 0;

    PyConfig config;
    PyConfig_InitIsolatedConfig(&config);
    config.site_import = 0;              /* no site-packages but the runtime's, no .pth files */
    config.write_bytecode = 0;           /* the unpacked FMU may be read-only; its modules are compiled */
    config.install_signal_handlers = 0;
    config.module_search_paths_set = 1;
    PyStatus status = PyConfig_SetBytesString(&config, &config.program_name, program);
    if (!PyStatus_Exception(status)) status = PyConfig_SetBytesString(&config, &config.home, runtime);
    for (size_t i = 0; i < sizeof SEARCH_PATH / sizeof *SEARCH_PATH && !PyStatus_Exception(status); ++i)
        status = append_path(&config, runtime, SEARCH_PATH[i]);
    if (!PyStatus_Exception(status)) status = Py_InitializeFromConfig(&config);
    PyConfig_Clear(&config);
    if (config_failed(status, "Py_InitializeFromConfig")) return 0;
    PyEval_SaveThread();                 /* pythonfmu takes the GIL itself in each call */
    return 1;
}

static int load_pythonfmu(const char *path)
{
    char error[MESSAGE_SIZE - 64];
    void *handle = library_open(path, error, sizeof error);
    if (handle == NULL) {
        snprintf(startup_error, sizeof startup_error, "pythonfmu's binary: %s", error);
        return 0;
    }
    const char *missing = fmi2_table_resolve(handle, &fmi);
    if (missing != NULL) {
        snprintf(startup_error, sizeof startup_error, "%s does not provide %s", path, missing);
        return 0;
    }
    return 1;
}

/* ---- serving requests ----------------------------------------------------------------------------- */

/* An instance the worker serves: its channel, its client's connection, pythonfmu's instance. */
typedef struct {
    _Atomic int used;                    /* published by the door thread, released by the main thread */
    _Atomic int orphaned;                /* its connection hung up: the main thread frees it */
    int socket;
    Channel channel;
    ChannelEvent wake_client;            /* Windows: the event its client sleeps on */
    uint32_t answered;                   /* the last request answered */
    char guid[GUID_SIZE];
    fmi2Component component;             /* pythonfmu's instance */
    int released;                        /* pythonfmu returned fmi2Fatal: it has released its slave */
    fmi2ValueReference *prefetch_list;
    uint32_t n_prefetch;
} Slot;

static Slot slots[MAX_SLOTS];
static Lock slots_lock = LOCK_INITIALIZER;
static int ending = 0;                   /* the last instance was freed: no more joins (under slots_lock) */
static WorkerControl *control;
#ifndef _WIN32
static char packages[64 * PACKAGES_SIZE];   /* "name=digest;..." of the code loaded (under slots_lock) */
static int output_fd = 1;
#endif

static fmi2CallbackFunctions callbacks = {worker_logger, calloc, free, NULL, NULL};

static unsigned char *request_copy = NULL;   /* the request, copied: the response is written over it */
static size_t request_cap = 0;
static void *scratch = NULL;                 /* results of a call before they are written */
static size_t scratch_cap = 0;

static void *scratch_of(size_t bytes)
{
    if (bytes > scratch_cap) {
        void *grown = realloc(scratch, bytes);
        if (grown == NULL) return NULL;
        scratch = grown;
        scratch_cap = bytes;
    }
    return scratch;
}

static fmi2Status note(Slot *slot, fmi2Status status)
{
    if (status == fmi2Fatal) slot->released = 1;
    return status;
}

/* The outputs of one operation of `slot`'s instance into `w`; returns the call's status. */
static fmi2Status serve(Slot *slot, uint32_t op, Reader *r, Writer *w)
{
    uint32_t n, m, k;
    const fmi2ValueReference *vr;
    char name[1024], guid[256], location[PATH_SIZE + 16];

    if (op == OP_INSTANTIATE) {
        take_string(r, name, sizeof name);
        int32_t type = take_i32(r);
        take_string(r, guid, sizeof guid);
        take_string(r, location, sizeof location);
        int32_t visible = take_i32(r);
        if (r->failed) return fmi2Error;
        /* logging stays on in pythonfmu: it drops errors too otherwise; the host side filters */
        slot->component = fmi.Instantiate(name, (fmi2Type)type, guid, location, &callbacks, visible, fmi2True);
        return slot->component != NULL ? fmi2OK : fmi2Error;
    }
    if (slot->component == NULL || slot->released) {
        log_error("the unit's instance %s", slot->component == NULL ? "was not created" : "failed before (fmi2Fatal)");
        return fmi2Error;
    }
    switch (op) {
    case OP_SETUP_EXPERIMENT: {
        int32_t has_tolerance = take_i32(r);
        double tolerance = take_f64(r), start = take_f64(r);
        int32_t has_stop = take_i32(r);
        double stop = take_f64(r);
        return note(slot, fmi.SetupExperiment(slot->component, has_tolerance, tolerance, start, has_stop, stop));
    }
    case OP_ENTER_INITIALIZATION_MODE: return note(slot, fmi.EnterInitializationMode(slot->component));
    case OP_EXIT_INITIALIZATION_MODE: return note(slot, fmi.ExitInitializationMode(slot->component));
    case OP_TERMINATE: return note(slot, fmi.Terminate(slot->component));
    case OP_RESET: return note(slot, fmi.Reset(slot->component));
    case OP_DO_STEP: {
        double t = take_f64(r), h = take_f64(r);
        int32_t no_prior = take_i32(r);
        return note(slot, fmi.DoStep(slot->component, t, h, no_prior));
    }
    case OP_CANCEL_STEP: return note(slot, fmi.CancelStep(slot->component));
    case OP_GET_REAL: case OP_GET_INTEGER: case OP_GET_BOOLEAN: case OP_GET_STRING: {
        vr = take_array(r, &n, sizeof *vr);
        size_t size = op == OP_GET_REAL ? sizeof(fmi2Real) : op == OP_GET_STRING ? sizeof(fmi2String)
                                                                                   : sizeof(fmi2Integer);
        void *values = scratch_of(n * size + 8);
        if (r->failed || values == NULL) return fmi2Error;
        fmi2Status s = op == OP_GET_REAL      ? fmi.GetReal(slot->component, vr, n, values)
                       : op == OP_GET_INTEGER ? fmi.GetInteger(slot->component, vr, n, values)
                       : op == OP_GET_BOOLEAN ? fmi.GetBoolean(slot->component, vr, n, values)
                                              : fmi.GetString(slot->component, vr, n, values);
        if (op == OP_GET_STRING) {
            put_u32(w, n);
            for (uint32_t i = 0; i < n; ++i) put_string(w, ((fmi2String *)values)[i]);
        } else {
            put_array(w, values, n, size);
        }
        return note(slot, s);
    }
    case OP_SET_REAL: case OP_SET_INTEGER: case OP_SET_BOOLEAN: {
        vr = take_array(r, &n, sizeof *vr);
        const void *values = take_array(r, &m, op == OP_SET_REAL ? sizeof(fmi2Real) : sizeof(fmi2Integer));
        if (r->failed || m != n) return fmi2Error;
        return note(slot, op == OP_SET_REAL      ? fmi.SetReal(slot->component, vr, n, values)
                    : op == OP_SET_INTEGER ? fmi.SetInteger(slot->component, vr, n, values)
                                           : fmi.SetBoolean(slot->component, vr, n, values));
    }
    case OP_SET_STRING: {
        vr = take_array(r, &n, sizeof *vr);
        fmi2String *values = scratch_of((size_t)n * sizeof *values + 8);
        if (r->failed || values == NULL) return fmi2Error;
        for (uint32_t i = 0; i < n; ++i) {   /* NUL-terminated copies, kept until the call returns */
            uint32_t length = take_u32(r);
            const char *text = take(r, length);
            char *copy = text != NULL ? strndup(text, length) : NULL;
            if (copy == NULL) {
                for (uint32_t j = 0; j < i; ++j) free((char *)values[j]);
                return fmi2Error;
            }
            values[i] = copy;
        }
        fmi2Status s = note(slot, fmi.SetString(slot->component, vr, n, values));
        for (uint32_t i = 0; i < n; ++i) free((char *)values[i]);
        return s;
    }
    case OP_GET_FMU_STATE: {
        fmi2FMUstate state = NULL;
        fmi2Status s = note(slot, fmi.GetFMUstate(slot->component, &state));
        put_u64(w, (uint64_t)(uintptr_t)state);
        return s;
    }
    case OP_SET_FMU_STATE: return note(slot, fmi.SetFMUstate(slot->component, (fmi2FMUstate)(uintptr_t)take_u64(r)));
    case OP_FREE_FMU_STATE: {
        fmi2FMUstate state = (fmi2FMUstate)(uintptr_t)take_u64(r);
        return note(slot, fmi.FreeFMUstate(slot->component, &state));
    }
    case OP_SERIALIZED_FMU_STATE_SIZE: {
        size_t size = 0;
        fmi2Status s = note(slot, fmi.SerializedFMUstateSize(slot->component, (fmi2FMUstate)(uintptr_t)take_u64(r), &size));
        put_u64(w, size);
        return s;
    }
    case OP_SERIALIZE_FMU_STATE: {
        fmi2FMUstate state = (fmi2FMUstate)(uintptr_t)take_u64(r);
        size_t size = (size_t)take_u64(r);
        fmi2Byte *bytes = scratch_of(size + 1);
        if (r->failed || bytes == NULL) return fmi2Error;
        fmi2Status s = note(slot, fmi.SerializeFMUstate(slot->component, state, bytes, size));
        put_array(w, bytes, (uint32_t)size, 1);
        return s;
    }
    case OP_DESERIALIZE_FMU_STATE: {
        const fmi2Byte *bytes = take_array(r, &n, 1);
        if (r->failed) return fmi2Error;
        fmi2FMUstate state = NULL;
        fmi2Status s = note(slot, fmi.DeSerializeFMUstate(slot->component, bytes, n, &state));
        put_u64(w, (uint64_t)(uintptr_t)state);
        return s;
    }
    case OP_GET_DIRECTIONAL_DERIVATIVE: {
        const fmi2ValueReference *unknown = take_array(r, &n, sizeof *unknown);
        const fmi2ValueReference *known = take_array(r, &m, sizeof *known);
        const fmi2Real *dv = take_array(r, &k, sizeof *dv);
        fmi2Real *out = scratch_of((size_t)n * sizeof *out + 8);
        if (r->failed || k != m || out == NULL) return fmi2Error;
        fmi2Status s = note(slot, fmi.GetDirectionalDerivative(slot->component, unknown, n, known, m, dv, out));
        put_array(w, out, n, sizeof *out);
        return s;
    }
    case OP_SET_REAL_INPUT_DERIVATIVES: {
        vr = take_array(r, &n, sizeof *vr);
        const fmi2Integer *order = take_array(r, &m, sizeof *order);
        const fmi2Real *values = take_array(r, &k, sizeof *values);
        if (r->failed || m != n || k != n) return fmi2Error;
        return note(slot, fmi.SetRealInputDerivatives(slot->component, vr, n, order, values));
    }
    case OP_GET_REAL_OUTPUT_DERIVATIVES: {
        vr = take_array(r, &n, sizeof *vr);
        const fmi2Integer *order = take_array(r, &m, sizeof *order);
        fmi2Real *out = scratch_of((size_t)n * sizeof *out + 8);
        if (r->failed || m != n || out == NULL) return fmi2Error;
        fmi2Status s = note(slot, fmi.GetRealOutputDerivatives(slot->component, vr, n, order, out));
        put_array(w, out, n, sizeof *out);
        return s;
    }
    case OP_GET_STATUS: case OP_GET_REAL_STATUS: case OP_GET_INTEGER_STATUS: case OP_GET_BOOLEAN_STATUS:
    case OP_GET_STRING_STATUS: {
        fmi2StatusKind kind = (fmi2StatusKind)take_i32(r);
        fmi2Status s;
        if (op == OP_GET_REAL_STATUS) {
            fmi2Real value = 0.0;
            s = fmi.GetRealStatus(slot->component, kind, &value);
            put_f64(w, value);
        } else if (op == OP_GET_STRING_STATUS) {
            fmi2String value = NULL;
            s = fmi.GetStringStatus(slot->component, kind, &value);
            put_string(w, value);
        } else {
            fmi2Integer value = 0;   /* fmi2Status, fmi2Integer and fmi2Boolean are all int */
            s = op == OP_GET_STATUS           ? fmi.GetStatus(slot->component, kind, (fmi2Status *)&value)
                : op == OP_GET_INTEGER_STATUS ? fmi.GetIntegerStatus(slot->component, kind, &value)
                                              : fmi.GetBooleanStatus(slot->component, kind, &value);
            put_i32(w, value);
        }
        return note(slot, s);
    }
    default:
        log_error("unknown request %u (the FMU's binary and worker come from different builds)", op);
        return fmi2Error;
    }
}

/* The values of the slot's prefetch list after the call, unless reading them logged or failed. */
static void prefetch(Slot *slot, Writer *w)
{
    fmi2Real *values = scratch_of((size_t)slot->n_prefetch * sizeof *values + 8);
    if (values == NULL || slot->component == NULL || slot->released || slot->n_prefetch == 0) {
        put_u32(w, 0);
        return;
    }
    capturing_prefetch = 1;
    prefetch_logged = 0;
    fmi2Status s = fmi.GetReal(slot->component, slot->prefetch_list, slot->n_prefetch, values);
    capturing_prefetch = 0;
    if (s != fmi2OK || prefetch_logged) {
        note(slot, s);
        put_u32(w, 0);
        return;
    }
    put_u32(w, 1);
    put_array(w, values, slot->n_prefetch, sizeof *values);
}

static int trace_fd = -1;                   /* WINGSIM_WORKER_TRACE's file, or -1 */

#ifdef _WIN32
static void trace(uint32_t op, long long began) { (void)op, (void)began; }   /* Linux only */
#else
static void trace(uint32_t op, long long began)
{
    char line[96];
    int n = snprintf(line, sizeof line, "%d %u %lld %lld\n", (int)getpid(), op, began, (long long)channel_now_ns());
    if (n > 0 && write(trace_fd, line, (size_t)n) < 0) trace_fd = -1;   /* one write: lines never mix */
}
#endif

/* Free the slot's instance; 1 if it is the last the worker serves, and the worker then ends (no more
 * joins). The slot itself is released by `release_slot`, once its answer is written. */
static int free_instance(Slot *slot)
{
    if (slot->component != NULL && !slot->released) fmi.FreeInstance(slot->component);
    slot->component = NULL;
    lock(&slots_lock);
    int last = 1;
    for (int i = 0; i < MAX_SLOTS; ++i) last &= (&slots[i] == slot || !atomic_load(&slots[i].used));
    if (last) ending = 1;
    unlock(&slots_lock);
    return last;
}

/* Release the slot (its instance freed): its channel unmapped, its connection closed by the door thread. */
static void release_slot(Slot *slot)
{
    free(slot->prefetch_list);
    slot->prefetch_list = NULL;
    slot->n_prefetch = 0;
    channel_close(&slot->channel);
    lock(&slots_lock);
    atomic_store(&slot->used, 0);
    unlock(&slots_lock);
}

/* Answer the request in the slot's channel: 1; 2 after OP_FREE_INSTANCE (the slot is then released), 0
 * after the last (the worker then exits); -1 when the request cannot be read or answered (out of memory):
 * the worker exits without an answer and every client reports it ended. */
static int handle(Slot *slot)
{
    long long began = channel_now_ns();
    Channel *channel = &slot->channel;
    if (!channel_sync(channel)) return -1;
    size_t length = channel->head->length;
    if (length > request_cap) {
        unsigned char *grown = realloc(request_copy, length);
        if (grown == NULL) return -1;
        request_copy = grown;
        request_cap = length;
    }
    memcpy(request_copy, channel->data, length);
    Reader r = {request_copy, 0, length, 0};
    uint32_t op = take_u32(&r), wants_prefetch = take_u32(&r), has_list = take_u32(&r);
    if (has_list) {
        uint32_t n;
        const fmi2ValueReference *list = take_array(&r, &n, sizeof *list);
        fmi2ValueReference *copy = n > 0 ? malloc(n * sizeof *copy) : NULL;
        if (list != NULL && (copy != NULL || n == 0)) {
            if (n > 0) memcpy(copy, list, n * sizeof *copy);
            free(slot->prefetch_list);
            slot->prefetch_list = copy;
            slot->n_prefetch = n;
        }
    }

    Writer w = {channel, 0, 0};
    put_i32(&w, 0);                   /* the status, written last */
    fmi2Status status = fmi2OK;
    int last = 0;
    if (op == OP_FREE_INSTANCE) {
        last = free_instance(slot);
    } else if (startup_error[0] != '\0') {
        log_error("%s", startup_error);
        status = fmi2Error;
    } else {
        status = serve(slot, op, &r, &w);
        if (r.failed && status < fmi2Error) {
            log_error("request %u was incomplete (the FMU's binary and worker come from different builds)", op);
            status = fmi2Error;
        }
    }
    put_u32(&w, (uint32_t)n_records);
    for (size_t i = 0; i < n_records; ++i) {
        put_i32(&w, records[i].status);
        put_string(&w, records[i].category);
        put_string(&w, records[i].message);
    }
    clear_records();
    if (wants_prefetch && startup_error[0] == '\0') prefetch(slot, &w);
    else put_u32(&w, 0);
    if (op == OP_FREE_INSTANCE) put_u32(&w, (uint32_t)last);
    if (w.failed) return -1;
    memcpy(channel->data, &(int32_t){(int32_t)status}, sizeof(int32_t));
    channel->head->length = w.pos;
    if (trace_fd >= 0) trace(op, began);
    return op != OP_FREE_INSTANCE ? 1 : last ? 0 : 2;
}

/* ---- the main loop: serve every slot's requests, sleep on the doorbell between them ---------------- */

#ifdef _WIN32
/* the Windows form of _exit: no DLL detach (pythonfmu's would finalize Python), no exit handlers */
#define end_worker(code) TerminateProcess(GetCurrentProcess(), (code))
#else
#define end_worker(code) _exit(code)
#endif

static ChannelEvent doorbell_event = NO_EVENT;   /* Windows: the event the worker sleeps on */

static void serve_forever(void)
{
    for (;;) {
        uint32_t seen = atomic_load(&control->doorbell);
        for (int i = 0; i < MAX_SLOTS; ++i) {
            Slot *slot = &slots[i];
            if (!atomic_load_explicit(&slot->used, memory_order_acquire)) continue;
            uint32_t request = atomic_load_explicit(&slot->channel.head->request, memory_order_acquire);
            if (request != slot->answered) {
                int go_on = handle(slot);
                if (go_on < 0) end_worker(1);
                slot->answered = request;
                channel_signal(&slot->channel.head->response, request, &slot->channel.head->client_sleeps,
                               slot->wake_client);
                if (go_on == 0) end_worker(0);  /* no exit handlers: pythonfmu's would run after its destructor */
                if (go_on == 2) release_slot(slot);
            } else if (atomic_load(&slot->orphaned)) {
                int last = free_instance(slot);
                release_slot(slot);
                if (last) end_worker(0);
            }
        }
        channel_wait(&control->doorbell, seen, &control->worker_sleeps, doorbell_event, SPIN_YIELD_NS, NULL, NULL);
    }
}

#ifdef _WIN32
#include "fmi_worker_win.c"
#else
/* ---- the door: joins, the lifeline, connections that hang up -------------------------------------- */

/* Whether the code a client brings ("name=digest;...") agrees with what the worker has loaded, and if so
 * add it (under slots_lock). */
static int compatible(const char *brought)
{
    char copy[PACKAGES_SIZE];
    snprintf(copy, sizeof copy, "%s", brought);
    for (char *save = NULL, *entry = strtok_r(copy, ";", &save); entry != NULL; entry = strtok_r(NULL, ";", &save)) {
        char *equal = strchr(entry, '=');
        if (equal == NULL) return 0;
        char name[256];
        snprintf(name, sizeof name, ";%.*s=", (int)(equal - entry), entry);
        const char *known = strstr(packages, name);
        if (known != NULL && strncmp(known + 1, entry, strlen(entry)) != 0) return 0;
        if (known != NULL && known[1 + strlen(entry)] != ';') return 0;
    }
    for (char *save = NULL, *entry = strtok_r(strcpy(copy, brought), ";", &save); entry != NULL;
         entry = strtok_r(NULL, ";", &save)) {
        char name[PACKAGES_SIZE + 2];
        snprintf(name, sizeof name, ";%s;", entry);
        if (strstr(packages, name) == NULL && strlen(packages) + strlen(entry) + 2 < sizeof packages) {
            if (packages[0] == '\0') strcat(packages, ";");
            strcat(packages, entry);
            strcat(packages, ";");
        }
    }
    return 1;
}

/* A client at the listening socket: accept it into a free slot, or refuse, saying why. */
static void join(int connection)
{
    JoinRequest request;
    int fds[4], n_fds = 0;
    JoinReply reply = {0, (int32_t)getpid(), ""};
    int ok = receive_with_fds(connection, &request, sizeof request, fds, 4, &n_fds);
    request.guid[GUID_SIZE - 1] = request.packages[PACKAGES_SIZE - 1] = '\0';
    Slot *slot = NULL;
    lock(&slots_lock);
    if (!ok || n_fds != 1 || request.magic != CHANNEL_MAGIC || request.version != CHANNEL_VERSION) {
        snprintf(reply.reason, sizeof reply.reason, "the request is not one of this version's");
    } else if (ending) {
        snprintf(reply.reason, sizeof reply.reason, "the worker is ending");
    } else {
        for (int i = 0; i < MAX_SLOTS; ++i) {
            if (atomic_load(&slots[i].used) && strcmp(slots[i].guid, request.guid) == 0) {
                snprintf(reply.reason, sizeof reply.reason, "it serves an instance of this FMU already");
                break;
            }
            if (slot == NULL && !atomic_load(&slots[i].used) && slots[i].socket < 0) slot = &slots[i];
        }
        if (reply.reason[0] == '\0' && slot == NULL) snprintf(reply.reason, sizeof reply.reason, "it is full");
        if (reply.reason[0] == '\0' && !compatible(request.packages))
            snprintf(reply.reason, sizeof reply.reason, "it runs other code of a package this FMU carries");
        struct stat info;
        if (reply.reason[0] == '\0') {
            Channel channel = {fds[0], 0, NULL, NULL};
            if (fstat(fds[0], &info) != 0 || !channel_map(&channel, (size_t)info.st_size)
                || channel.head->magic != CHANNEL_MAGIC) {
                snprintf(reply.reason, sizeof reply.reason, "its channel cannot be mapped");
            } else {
                memset(slot, 0, sizeof *slot);
                slot->channel = channel;
                slot->socket = connection;
                slot->answered = atomic_load(&channel.head->response);
                snprintf(slot->guid, sizeof slot->guid, "%s", request.guid);
                reply.accepted = 1;
            }
        }
    }
    int sent = reply.accepted ? send_with_fds(connection, &reply, sizeof reply, (int[]){CONTROL_FD, output_fd}, 2)
                              : send_with_fds(connection, &reply, sizeof reply, NULL, 0);
    if (reply.accepted && sent) {
        atomic_store(&slot->used, 1);   /* published: the main thread serves it from now on */
    } else {
        if (reply.accepted) {           /* the client left before the answer */
            munmap(slot->channel.head, slot->channel.mapped);
            close(slot->channel.fd);
            slot->socket = -1;
        } else if (n_fds == 1) {
            close(fds[0]);
        }
        close(connection);
    }
    unlock(&slots_lock);
    channel_ring(&control->doorbell, &control->worker_sleeps, NO_EVENT);
}

/* The door thread: waits on the lifeline (the host gone: exit at once), the listening socket (a join)
 * and every slot's connection (hung up: the slot is orphaned, the main thread frees it). */
static void *door(void *unused)
{
    (void)unused;
    for (;;) {
        struct pollfd fds[2 + MAX_SLOTS];
        int index[2 + MAX_SLOTS], n = 0;
        lock(&slots_lock);
        for (int i = 0; i < MAX_SLOTS; ++i) {
            if (!atomic_load(&slots[i].used) && slots[i].socket >= 0) {
                close(slots[i].socket);        /* a slot the main thread released */
                slots[i].socket = -1;
            }
        }
        unlock(&slots_lock);
        fds[n++] = (struct pollfd){LIFELINE_FD, POLLIN, 0};
        fds[n++] = (struct pollfd){LISTEN_FD, POLLIN, 0};
        for (int i = 0; i < MAX_SLOTS; ++i) {
            if (atomic_load(&slots[i].used) && !atomic_load(&slots[i].orphaned)) {
                index[n] = i;
                fds[n++] = (struct pollfd){slots[i].socket, POLLIN, 0};
            }
        }
        /* a slot published or freed meanwhile is seen within the timeout */
        if (poll(fds, (nfds_t)n, 100) < 0 && errno != EINTR) _exit(1);
        if (fds[0].revents) _exit(0);   /* the host is gone: nothing to finish, nobody to answer */
        if (fds[1].revents & POLLIN) {
            int connection = accept4(LISTEN_FD, NULL, NULL, SOCK_CLOEXEC);
            if (connection >= 0) join(connection);
        }
        for (int k = 2; k < n; ++k) {
            if (fds[k].revents) {
                atomic_store(&slots[index[k]].orphaned, 1);
                channel_ring(&control->doorbell, &control->worker_sleeps, NO_EVENT);
            }
        }
    }
    return NULL;
}

/* Close every descriptor from `first` on: those the host had open without close-on-exec (a pipe, a
 * socket, a file) would otherwise stay open as long as the worker lives, hiding their end from whoever
 * waits for it. */
static void close_inherited(int first)
{
    if (syscall(SYS_close_range, (unsigned)first, ~0U, 0) == 0) return;
    DIR *fds = opendir("/proc/self/fd");          /* kernels before 5.9 */
    if (fds == NULL) return;
    for (struct dirent *entry; (entry = readdir(fds)) != NULL;) {
        int fd = atoi(entry->d_name);
        if (fd >= first && fd != dirfd(fds)) close(fd);
    }
    closedir(fds);
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: %s PYTHONFMU_BINARY RUNTIME_FOLDER (started by a wingsim FMU)\n", argv[0]);
        return 2;
    }
    close_inherited(LISTEN_FD + 1);
    for (int fd = LIFELINE_FD; fd <= LISTEN_FD; ++fd)
        fcntl(fd, F_SETFD, FD_CLOEXEC);          /* a process Python starts must not hold them */
    output_fd = fcntl(1, F_DUPFD_CLOEXEC, 10);
    control = mmap(NULL, WORKER_CONTROL_SIZE, PROT_READ | PROT_WRITE, MAP_SHARED, CONTROL_FD, 0);
    if (control == MAP_FAILED || control->magic != CHANNEL_MAGIC || control->version != CHANNEL_VERSION) return 4;
    const char *trace_file = getenv("WINGSIM_WORKER_TRACE");
    if (trace_file != NULL && trace_file[0] != '\0')
        trace_fd = open(trace_file, O_WRONLY | O_APPEND | O_CREAT | O_CLOEXEC, 0644);
    for (int i = 0; i < MAX_SLOTS; ++i) slots[i].socket = -1;
    pthread_t door_thread;
    if (pthread_create(&door_thread, NULL, door, NULL) != 0) return 3;
    if (start_python(argv[0], argv[2])) load_pythonfmu(argv[1]);
    serve_forever();
}
#endif
