/* The native binary of a wingsim FMU: checks what the Python slave cannot and forwards every FMI 2.0
 * Co-Simulation call, in one of two ways chosen when `wingsim build` compiles it
 * (orchestrator/build/native_binary.py):
 *
 * - ordinary FMU: to pythonfmu's unchanged binary beside it, in the host process. pythonfmu's binary
 *   leaves the Python C API to be supplied by the host, so a host without Python (a C tool started with
 *   an empty environment) cannot load it: this shim brings the build interpreter's libpython into the
 *   process when no interpreter runs yet, initialised with the build environment's python as program
 *   name (its pyvenv.cfg and site-packages, whatever the host's environment says). It never links
 *   libpython: every Python function is looked up with dlsym.
 * - standalone FMU (SHIM_WORKER defined): to the unit's own worker process, which runs the Python
 *   runtime the FMU carries (worker_client.c, fmi_worker.c). Nothing of Python enters the host process.
 *   This is the only kind compiled for Windows too (with mingw-w64: binaries/win64 of a standalone FMU);
 *   native_platform.h holds what differs between the two systems here.
 *
 * Either way it checks the component and FMU state pointers, the GUID, the FMU type and the resource
 * location.
 *
 * Status rule: a forwarded call returns the worse of the inner status and the worst status the
 * instance logged during that call, because the Python slaves refuse a call by logging an error
 * (pythonfmu 0.7.0 maps every return of a Python method to fmi2OK).
 *
 * Compile-time constants (all C string literals):
 *   SHIM_GUID       the GUID of the FMU's modelDescription.xml
 *   SHIM_INNER      file name of pythonfmu's binary, in the folder of this one
 *   SHIM_LIBPYTHON  ordinary FMU: absolute path of the build interpreter's shared libpython
 *   SHIM_PYTHON     ordinary FMU: the build environment's python executable (sys.executable)
 *   SHIM_WORKER     standalone FMU: file name of the worker executable, in the folder of this one
 */
#define _GNU_SOURCE 1
#ifndef SHIM_WORKER
#include <Python.h> /* the PyConfig layout of the build interpreter; no function of it is linked */
#endif

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2_table.h"
#include "fmi2_uri.h"
#include "native_platform.h"

#if !defined(SHIM_GUID) || !defined(SHIM_INNER)
#error "SHIM_GUID and SHIM_INNER must be defined"
#endif
#if !defined(SHIM_WORKER) && (!defined(SHIM_LIBPYTHON) || !defined(SHIM_PYTHON))
#error "an ordinary FMU's shim needs SHIM_LIBPYTHON and SHIM_PYTHON"
#endif

#define CATEGORY_ERROR "logStatusError"
#define CATEGORY_WARNING "logStatusWarning"
#define PATH_SIZE 4096
#define MESSAGE_SIZE (2 * PATH_SIZE + 1024)

/* ------------------------------------------------------------------------------------------------ */
/* The inner functions: pythonfmu's binary, loaded by the first fmi2Instantiate and unloaded with the
 * shim; or the worker client's. */

static Lock load_lock = LOCK_INITIALIZER;
static int loaded = 0;                   /* Python runs and the inner functions are resolved */
static char load_error[MESSAGE_SIZE];    /* why loading failed; loading is not retried after that */
static Fmi2Table inner;

/* ------------------------------------------------------------------------------------------------ */
/* Instances */

typedef struct Instance {
    struct Instance *next;               /* list of live instances: a foreign pointer is refused */
    fmi2Component component;             /* pythonfmu's */
    fmi2CallbackFunctions host;          /* the host's callbacks, as given */
    fmi2CallbackFunctions wrapped;       /* given to pythonfmu: the shim's logger, this record */
    char *name;
    fmi2Status worst;                    /* worst status logged during the current call */
    int dead;                            /* a call ended in fmi2Fatal: the instance is unusable */
    int released;                        /* pythonfmu returned fmi2Fatal: it released its slave */
    int logging_on;                      /* the host's fmi2SetDebugLogging */
    size_t n_categories;
    char **categories;
    size_t n_states, cap_states;
    fmi2FMUstate *states;                /* states handed out and not yet freed */
} Instance;

static Lock instances_lock = LOCK_INITIALIZER;
static Instance *instances = NULL;

static int is_live(const Instance *inst)
{
    int found = 0;
    lock(&instances_lock);
    for (const Instance *i = instances; i != NULL; i = i->next) {
        if (i == inst) {
            found = 1;
            break;
        }
    }
    unlock(&instances_lock);
    return found;
}

/* Pass `text` to a host logger as its printf format: every '%' doubled. */
static void log_text(const fmi2CallbackFunctions *cb, const char *instance_name, fmi2Status status,
                     const char *text)
{
    if (cb == NULL || cb->logger == NULL) return;
    char escaped[2 * MESSAGE_SIZE];
    size_t k = 0;
    for (const char *p = text; *p != '\0' && k + 2 < sizeof escaped; ++p) {
        if (*p == '%') escaped[k++] = '%';
        escaped[k++] = *p;
    }
    escaped[k] = '\0';
    cb->logger(cb->componentEnvironment, instance_name != NULL ? instance_name : "",
               status, status >= fmi2Error ? CATEGORY_ERROR : CATEGORY_WARNING, escaped);
}

static void log_to(const fmi2CallbackFunctions *cb, const char *instance_name, fmi2Status status,
                   const char *format, ...)
{
    char text[MESSAGE_SIZE];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    log_text(cb, instance_name, status, text);
}

#define REFUSE(inst, ...) (log_to(&(inst)->host, (inst)->name, fmi2Error, __VA_ARGS__), fmi2Error)

static int category_enabled(const Instance *inst, const char *category)
{
    if (inst->n_categories == 0) return 1;
    if (category == NULL) return 0;
    for (size_t i = 0; i < inst->n_categories; ++i)
        if (strcmp(inst->categories[i], category) == 0) return 1;
    return 0;
}

/* The logger pythonfmu calls: records the status for the status rule, then forwards to the host.
 * pythonfmu passes its message as the printf format, without arguments; it is passed on as such. */
static void shim_logger(fmi2ComponentEnvironment env, fmi2String instance_name, fmi2Status status,
                        fmi2String category, fmi2String message, ...)
{
    Instance *inst = (Instance *)env;
    if (inst == NULL || message == NULL) return;
    if (status <= fmi2Fatal && status > inst->worst) inst->worst = status;
    /* pythonfmu always logs (it drops every message, errors included, when logging is off); the
     * host's choice applies here: a message that is not fmi2OK always reaches it. */
    if (status == fmi2OK && !(inst->logging_on && category_enabled(inst, category))) return;
    if (inst->host.logger != NULL)
        inst->host.logger(inst->host.componentEnvironment, instance_name, status, category, message);
}

static fmi2Status worse(fmi2Status a, fmi2Status b)
{
    if (a > fmi2Fatal) return b; /* fmi2Pending is not a failure */
    if (b > fmi2Fatal) return a;
    return a > b ? a : b;
}

/* The checks every call shares; NULL if the call is refused (*status set). */
static Instance *enter(fmi2Component c, const char *function, fmi2Status *status)
{
    Instance *inst = (Instance *)c;
    if (inst == NULL || !is_live(inst)) {
        /* no instance, so no logger to tell the reason to */
        *status = fmi2Error;
        return NULL;
    }
    if (inst->dead) {
        log_to(&inst->host, inst->name, fmi2Fatal,
               "%s: the instance failed with fmi2Fatal before and cannot be used any more", function);
        *status = fmi2Fatal;
        return NULL;
    }
    inst->worst = fmi2OK;
    return inst;
}

/* The status rule, and the instance is retired after fmi2Fatal. */
static fmi2Status leave(Instance *inst, fmi2Status inner_status)
{
    fmi2Status status = worse(inner_status, inst->worst);
    if (inner_status == fmi2Fatal) inst->released = 1;
    if (status == fmi2Fatal) inst->dead = 1;
    return status;
}

#define FORWARD(function, c, ...)                                                                  \
    do {                                                                                           \
        fmi2Status refused_;                                                                       \
        Instance *inst_ = enter((c), #function, &refused_);                                        \
        if (inst_ == NULL) return refused_;                                                        \
        return leave(inst_, inner.function(inst_->component, __VA_ARGS__));                        \
    } while (0)

#define FORWARD0(function, c)                                                                      \
    do {                                                                                           \
        fmi2Status refused_;                                                                       \
        Instance *inst_ = enter((c), #function, &refused_);                                        \
        if (inst_ == NULL) return refused_;                                                        \
        return leave(inst_, inner.function(inst_->component));                                     \
    } while (0)

/* ---- FMU states handed out by this instance ---- */

static long state_index(const Instance *inst, fmi2FMUstate state)
{
    for (size_t i = 0; i < inst->n_states; ++i)
        if (inst->states[i] == state) return (long)i;
    return -1;
}

static int add_state(Instance *inst, fmi2FMUstate state)
{
    if (inst->n_states == inst->cap_states) {
        size_t cap = inst->cap_states ? 2 * inst->cap_states : 8;
        fmi2FMUstate *grown = realloc(inst->states, cap * sizeof *grown);
        if (grown == NULL) return 0;
        inst->states = grown;
        inst->cap_states = cap;
    }
    inst->states[inst->n_states++] = state;
    return 1;
}

static void remove_state(Instance *inst, fmi2FMUstate state)
{
    long i = state_index(inst, state);
    if (i >= 0) inst->states[i] = inst->states[--inst->n_states];
}

#ifndef SHIM_WORKER
/* ------------------------------------------------------------------------------------------------ */
/* Loading Python and pythonfmu's binary */

typedef int IsInitializedFn(void);
typedef PyStatus PreInitializeFn(const PyPreConfig *);
typedef void PreConfigInitFn(PyPreConfig *);
typedef void ConfigInitFn(PyConfig *);
typedef PyStatus ConfigSetBytesStringFn(PyConfig *, wchar_t **, const char *);
typedef PyStatus InitializeFromConfigFn(const PyConfig *);
typedef void ConfigClearFn(PyConfig *);
typedef int StatusExceptionFn(PyStatus);
typedef PyThreadState *SaveThreadFn(void);

#define NAME_TEXT(x) #x
#define NUMBER_TEXT(x) NAME_TEXT(x)
#define LIBPYTHON_NAME "libpython" NUMBER_TEXT(PY_MAJOR_VERSION) "." NUMBER_TEXT(PY_MINOR_VERSION) ".so.1.0"

/* The Python this process starts (choose_python): the build environment's, or the one $WINGSIM_PYTHON names. */
static char python[PATH_SIZE], libpython[PATH_SIZE];

static int readable(const char *path) { return path[0] != '\0' && access(path, R_OK) == 0; }

/* The shared libpython of the interpreter `python` (same minor version as the build's): under its
 * installation's lib/, under the lib/ of the base installation a venv's pyvenv.cfg names, or in the
 * system's library folders. */
static int find_libpython(const char *python_path, char *out, size_t size)
{
    char real[PATH_SIZE], folder[PATH_SIZE], line[PATH_SIZE];
    if (realpath(python_path, real) != NULL) {
        char *slash = strrchr(real, '/');        /* .../prefix/bin/python -> .../prefix */
        if (slash != NULL) *slash = '\0';
        slash = strrchr(real, '/');
        if (slash != NULL) *slash = '\0';
        snprintf(out, size, "%s/lib/%s", real, LIBPYTHON_NAME);
        if (readable(out)) return 1;
    }
    snprintf(folder, sizeof folder, "%s", python_path);   /* a venv: <venv>/bin/python, <venv>/pyvenv.cfg */
    for (int up = 0; up < 2; ++up) {
        char *slash = strrchr(folder, '/');
        if (slash != NULL) *slash = '\0';
    }
    snprintf(line, sizeof line, "%s/pyvenv.cfg", folder);
    FILE *cfg = fopen(line, "r");
    while (cfg != NULL && fgets(line, sizeof line, cfg) != NULL) {
        char home[PATH_SIZE];
        if (sscanf(line, " home = %4095[^\n]", home) == 1) {
            snprintf(out, size, "%s/../lib/%s", home, LIBPYTHON_NAME);
            if (readable(out)) break;
            out[0] = '\0';
        }
    }
    if (cfg != NULL) fclose(cfg);
    if (readable(out)) return 1;
    static const char *system_folders[] = {"/usr/lib/x86_64-linux-gnu", "/usr/lib64", "/usr/lib", "/usr/local/lib"};
    for (size_t i = 0; i < sizeof system_folders / sizeof *system_folders; ++i) {
        snprintf(out, size, "%s/%s", system_folders[i], LIBPYTHON_NAME);
        if (readable(out)) return 1;
    }
    return 0;
}

/* The build environment's Python, or $WINGSIM_PYTHON with $WINGSIM_LIBPYTHON (else its libpython found by
 * find_libpython). 0 and load_error when it cannot be used. */
static int choose_python(void)
{
    const char *chosen = getenv("WINGSIM_PYTHON");
    if (chosen == NULL || chosen[0] == '\0') {
        snprintf(python, sizeof python, "%s", SHIM_PYTHON);
        snprintf(libpython, sizeof libpython, "%s", SHIM_LIBPYTHON);
        if (access(libpython, R_OK) != 0 || access(python, X_OK) != 0) {
            snprintf(load_error, sizeof load_error,
                     "the Python environment this FMU was built in is missing: %s (its library %s): rebuild the "
                     "FMU with wingsim build, set WINGSIM_PYTHON to the python of another environment with numpy "
                     "and scipy (Python %d.%d), or build a standalone FMU (wingsim build --standalone)",
                     access(python, X_OK) != 0 ? python : libpython, libpython, PY_MAJOR_VERSION, PY_MINOR_VERSION);
            return 0;
        }
        return 1;
    }
    snprintf(python, sizeof python, "%s", chosen);
    if (access(python, X_OK) != 0) {
        snprintf(load_error, sizeof load_error, "WINGSIM_PYTHON=%s: not an executable file", python);
        return 0;
    }
    const char *library = getenv("WINGSIM_LIBPYTHON");
    if (library != NULL && library[0] != '\0') {
        snprintf(libpython, sizeof libpython, "%s", library);
        if (access(libpython, R_OK) == 0) return 1;
        snprintf(load_error, sizeof load_error, "WINGSIM_LIBPYTHON=%s: no such file", libpython);
        return 0;
    }
    if (find_libpython(python, libpython, sizeof libpython)) return 1;
    snprintf(load_error, sizeof load_error,
             "WINGSIM_PYTHON=%s: its shared library %s was not found (under its installation's lib/, the base "
             "installation its pyvenv.cfg names, or the system's library folders); set WINGSIM_LIBPYTHON to it",
             python, LIBPYTHON_NAME);
    return 0;
}

static void *need(void *handle, const char *symbol)
{
    void *f = dlsym(handle, symbol);
    if (f == NULL)
        snprintf(load_error, sizeof load_error, "%s does not provide %s", libpython, symbol);
    return f;
}

static int failed_status(StatusExceptionFn *exception, PyStatus status, const char *step)
{
    if (!exception(status)) return 0;
    snprintf(load_error, sizeof load_error, "starting Python (%s, %s) failed in %s: %s", libpython,
             python, status.func != NULL ? status.func : step,
             status.err_msg != NULL ? status.err_msg : "it asked to exit");
    return 1;
}

/* Start the build interpreter (or $WINGSIM_PYTHON's) in this process unless one runs already. 0 and
 * load_error on failure. */
static int start_python(void)
{
    IsInitializedFn *running = (IsInitializedFn *)dlsym(RTLD_DEFAULT, "Py_IsInitialized");
    if (running != NULL && running()) return 1; /* a Python host (fmpy, libcosimpy): its interpreter */
    if (!choose_python()) return 0;
    /* RTLD_GLOBAL: pythonfmu's binary and Python's extension modules take the C API from it */
    void *lib = dlopen(libpython, RTLD_NOW | RTLD_GLOBAL | RTLD_NODELETE);
    if (lib == NULL) {
        snprintf(load_error, sizeof load_error, "cannot load %s: %s", libpython, dlerror());
        return 0;
    }
    IsInitializedFn *is_initialized = (IsInitializedFn *)need(lib, "Py_IsInitialized");
    if (is_initialized == NULL) return 0;
    if (running != NULL && running != is_initialized) {
        Dl_info info;
        const char *other = dladdr((void *)running, &info) && info.dli_fname ? info.dli_fname : "?";
        snprintf(load_error, sizeof load_error,
                 "another Python runtime (%s) is loaded in this process, not initialised; this FMU "
                 "needs %s", other, libpython);
        return 0;
    }
    if (is_initialized()) return 1;

    PreConfigInitFn *preconfig_init = (PreConfigInitFn *)need(lib, "PyPreConfig_InitPythonConfig");
    PreInitializeFn *preinitialize = (PreInitializeFn *)need(lib, "Py_PreInitialize");
    ConfigInitFn *config_init = (ConfigInitFn *)need(lib, "PyConfig_InitPythonConfig");
    ConfigSetBytesStringFn *set_string = (ConfigSetBytesStringFn *)need(lib, "PyConfig_SetBytesString");
    InitializeFromConfigFn *initialize = (InitializeFromConfigFn *)need(lib, "Py_InitializeFromConfig");
    ConfigClearFn *config_clear = (ConfigClearFn *)need(lib, "PyConfig_Clear");
    StatusExceptionFn *exception = (StatusExceptionFn *)need(lib, "PyStatus_Exception");
    SaveThreadFn *save_thread = (SaveThreadFn *)need(lib, "PyEval_SaveThread");
    if (!preconfig_init || !preinitialize || !config_init || !set_string || !initialize || !config_clear
        || !exception || !save_thread)
        return 0;

    /* The host's locale and environment stay as they are: no setlocale, no LC_CTYPE coercion,
     * UTF-8 for file names and standard streams, PYTHON* variables ignored. */
    PyPreConfig preconfig;
    preconfig_init(&preconfig);
    preconfig.use_environment = 0;
    preconfig.parse_argv = 0;
    preconfig.configure_locale = 0;
    preconfig.coerce_c_locale = 0;
    preconfig.coerce_c_locale_warn = 0;
    preconfig.utf8_mode = 1;
    if (failed_status(exception, preinitialize(&preconfig), "Py_PreInitialize")) return 0;

    PyConfig config;
    config_init(&config);
    config.parse_argv = 0;
    config.install_signal_handlers = 0; /* the host's signals stay the host's */
    config.use_environment = 0;          /* a host's PYTHONHOME/PYTHONPATH cannot redirect it */
    /* the build environment's python as program name: getpath finds its pyvenv.cfg, the base
     * installation's standard library and the environment's site-packages */
    PyStatus status = set_string(&config, &config.program_name, python);
    if (!exception(status)) status = initialize(&config);
    config_clear(&config);
    if (failed_status(exception, status, "Py_InitializeFromConfig")) return 0;
    /* release the GIL: pythonfmu takes it with PyGILState_Ensure on whichever thread calls */
    save_thread();
    return 1;
}

/* The folder of this shim, where pythonfmu's binary is. */
static int inner_path(char *path, size_t size)
{
    Dl_info info;
    if (!dladdr((void *)&inner_path, &info) || info.dli_fname == NULL) {
        snprintf(load_error, sizeof load_error, "cannot find the path of the FMU's binary (dladdr failed)");
        return 0;
    }
    const char *slash = strrchr(info.dli_fname, '/');
    size_t dir = slash != NULL ? (size_t)(slash - info.dli_fname) + 1 : 0;
    if (dir + strlen(SHIM_INNER) + 1 > size) {
        snprintf(load_error, sizeof load_error, "the FMU's path is too long: %s", info.dli_fname);
        return 0;
    }
    memcpy(path, info.dli_fname, dir);
    strcpy(path + dir, SHIM_INNER);
    return 1;
}

/* pythonfmu 0.7.0 keeps its interpreter guard in a static shared_ptr, destroyed by an exit handler, and
 * resets it again from its ELF destructor. Unloaded by dlclose, the destructor runs first: fine. Still
 * loaded at exit, the exit handler runs first and the destructor then resets a destroyed pointer: a use
 * after free that corrupts the heap (the process aborts in a later free). So the shim resets the guard
 * through pythonfmu's own function before either: from an exit handler registered after pythonfmu's
 * (it runs first) and, when the host unloads the shim, from its destructor, which also unloads
 * pythonfmu's binary. */
static void *inner_handle = NULL;
static void (*release_python_guard)(void) = NULL;
static int exiting = 0;

static void reset_guard_at_exit(void)
{
    exiting = 1;
    if (release_python_guard != NULL) release_python_guard();
}

__attribute__((destructor)) static void unload_inner(void)
{
    /* at exit the exit handler has run and the process is going away: nothing to unload */
    if (exiting || inner_handle == NULL) return;
    if (release_python_guard != NULL) release_python_guard();
    release_python_guard = NULL;
    dlclose(inner_handle);
    inner_handle = NULL;
}

static int load_inner(void)
{
    char path[PATH_SIZE];
    if (!inner_path(path, sizeof path)) return 0;
    if (access(path, R_OK) != 0) {
        snprintf(load_error, sizeof load_error, "pythonfmu's binary is missing from the FMU: %s", path);
        return 0;
    }
    void *handle = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (handle == NULL) {
        snprintf(load_error, sizeof load_error, "cannot load %s: %s", path, dlerror());
        return 0;
    }
    inner_handle = handle;
    const char *missing = fmi2_table_resolve(handle, &inner);
    if (missing != NULL) {
        snprintf(load_error, sizeof load_error, "%s does not provide %s", path, missing);
        return 0;
    }
    release_python_guard = (void (*)(void))dlsym(handle, "finalizePythonInterpreter");
    if (release_python_guard != NULL) atexit(reset_guard_at_exit);
    return 1;
}

/* Python and pythonfmu's binary, once per process; a failure is remembered, not retried (a Python
 * that failed to start cannot be started again). */
static int ensure_loaded(void)
{
    lock(&load_lock);
    if (!loaded && load_error[0] == '\0' && start_python() && load_inner()) loaded = 1;
    int ok = loaded;
    unlock(&load_lock);
    return ok;
}

/* pythonfmu releases its slave when it returns fmi2Fatal: freeing it again would corrupt Python */
#define INNER_RELEASES_ON_FATAL 1
#else
#include "worker_client.c"

/* The worker client: each instance starts its own worker in fmi2Instantiate. */
static int ensure_loaded(void)
{
    lock(&load_lock);
    inner = worker_table;
    loaded = 1;
    unlock(&load_lock);
    return 1;
}

/* the worker keeps track of pythonfmu's fmi2Fatal itself; the client always ends the worker */
#define INNER_RELEASES_ON_FATAL 0
#endif

/* The resource location: pythonfmu strips "file://" and decodes only "%20"; other spellings of a
 * file URI (file:/path, file://localhost/path, percent escapes) are turned into that form
 * (fmi2_uri.h; pythonfmu appends "/slavemodule.txt", so no trailing '/'). */

/* ------------------------------------------------------------------------------------------------ */
/* FMI 2.0 functions */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    if (functions == NULL || functions->logger == NULL) return NULL; /* nobody to tell why */
    const char *name = instanceName != NULL ? instanceName : "";
    if (instanceName == NULL || instanceName[0] == '\0') {
        log_to(functions, name, fmi2Error, "fmi2Instantiate: the instance name is empty");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        log_to(functions, name, fmi2Error,
               "fmi2Instantiate: this FMU supports Co-Simulation only, not Model Exchange");
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, SHIM_GUID) != 0) {
        log_to(functions, name, fmi2Error,
               "fmi2Instantiate: GUID %s does not match this FMU's %s (its modelDescription.xml and "
               "binary come from different builds)", fmuGUID != NULL ? fmuGUID : "(null)", SHIM_GUID);
        return NULL;
    }
    char resources[PATH_SIZE];
    if (fmuResourceLocation == NULL || !file_uri_to_path(fmuResourceLocation, resources, sizeof resources)) {
        log_to(functions, name, fmi2Error,
               "fmi2Instantiate: the resource location %s is not a file URI of a local folder",
               fmuResourceLocation != NULL ? fmuResourceLocation : "(null)");
        return NULL;
    }
    if (strstr(resources, "%20") != NULL) { /* pythonfmu would read it as a space */
        log_to(functions, name, fmi2Error,
               "fmi2Instantiate: pythonfmu cannot load from %s: its path contains \"%%20\"", resources);
        return NULL;
    }
    char slave_module[PATH_SIZE + 32];
    snprintf(slave_module, sizeof slave_module, "%s/slavemodule.txt", resources);
    if (!file_readable(slave_module)) {
        log_to(functions, name, fmi2Error,
               "fmi2Instantiate: %s is missing: %s is not this FMU's unpacked resources folder",
               slave_module, fmuResourceLocation);
        return NULL;
    }
    if (!ensure_loaded()) {
        log_to(functions, name, fmi2Error, "fmi2Instantiate: %s", load_error);
        return NULL;
    }

    Instance *inst = calloc(1, sizeof *inst);
    char *uri = malloc(strlen(resources) + 9);
    if (inst == NULL || uri == NULL || (inst->name = strdup(name)) == NULL) {
        free(inst != NULL ? inst->name : NULL);
        free(inst);
        free(uri);
        log_to(functions, name, fmi2Error, "fmi2Instantiate: out of memory");
        return NULL;
    }
    /* file:///path, and on Windows file:///C:/path: pythonfmu's win64 binary drops the first 8 characters */
    strcpy(uri, resources[0] == '/' ? "file://" : "file:///");
    strcat(uri, resources);
    memcpy(&inst->host, functions, sizeof inst->host);
    fmi2CallbackFunctions wrapped = {shim_logger, functions->allocateMemory, functions->freeMemory,
                                     functions->stepFinished, inst};
    memcpy(&inst->wrapped, &wrapped, sizeof wrapped);
    inst->logging_on = loggingOn != fmi2False;
    /* pythonfmu's logging stays on: it would drop errors too, and the status rule needs them */
    inst->component = inner.Instantiate(name, fmuType, fmuGUID, uri, &inst->wrapped, visible, fmi2True);
    free(uri);
    if (inst->component == NULL) {
        log_to(functions, name, fmi2Error, "fmi2Instantiate: the Python slave could not be created");
        free(inst->name);
        free(inst);
        return NULL;
    }
    lock(&instances_lock);
    inst->next = instances;
    instances = inst;
    unlock(&instances_lock);
    return inst;
}

void fmi2FreeInstance(fmi2Component c)
{
    Instance *inst = (Instance *)c;
    if (inst == NULL) return;
    lock(&instances_lock);
    Instance **link = &instances;
    while (*link != NULL && *link != inst) link = &(*link)->next;
    int found = *link != NULL;
    if (found) *link = inst->next;
    unlock(&instances_lock);
    if (!found) return;
    /* After returning fmi2Fatal (a Python exception) pythonfmu 0.7.0 has released its Python slave
     * already; freeing it again corrupts Python's reference counts, so that one is left as it is. A
     * worker ends with its instance, states and all. */
    if (!INNER_RELEASES_ON_FATAL) {
        inner.FreeInstance(inst->component);
    } else if (!inst->released) {
        for (size_t i = 0; i < inst->n_states; ++i) {
            fmi2FMUstate s = inst->states[i];
            inner.FreeFMUstate(inst->component, &s);
        }
        inner.FreeInstance(inst->component);
    }
    for (size_t i = 0; i < inst->n_categories; ++i) free(inst->categories[i]);
    free(inst->categories);
    free(inst->states);
    free(inst->name);
    free(inst);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    fmi2Status refused;
    Instance *inst = enter(c, "fmi2SetDebugLogging", &refused);
    if (inst == NULL) return refused;
    if (nCategories > 0 && categories == NULL)
        return REFUSE(inst, "fmi2SetDebugLogging: %zu categories but no array", nCategories);
    for (size_t i = 0; i < nCategories; ++i)
        if (categories[i] == NULL)
            return REFUSE(inst, "fmi2SetDebugLogging: category %zu is NULL", i);
    char **copy = nCategories > 0 ? calloc(nCategories, sizeof *copy) : NULL;
    if (nCategories > 0 && copy == NULL) return REFUSE(inst, "fmi2SetDebugLogging: out of memory");
    for (size_t i = 0; i < nCategories; ++i) {
        if ((copy[i] = strdup(categories[i])) == NULL) {
            for (size_t j = 0; j < i; ++j) free(copy[j]);
            free(copy);
            return REFUSE(inst, "fmi2SetDebugLogging: out of memory");
        }
    }
    for (size_t i = 0; i < inst->n_categories; ++i) free(inst->categories[i]);
    free(inst->categories);
    inst->categories = copy;
    inst->n_categories = nCategories;
    inst->logging_on = loggingOn != fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    FORWARD(SetupExperiment, c, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime);
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { FORWARD0(EnterInitializationMode, c); }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { FORWARD0(ExitInitializationMode, c); }
fmi2Status fmi2Terminate(fmi2Component c) { FORWARD0(Terminate, c); }
fmi2Status fmi2Reset(fmi2Component c) { FORWARD0(Reset, c); }

/* vr[] and value[] must exist when nvr > 0 */
#define CHECK_ARRAYS(inst, function, vr, nvr, value)                                               \
    do {                                                                                           \
        if ((nvr) > 0 && ((vr) == NULL || (value) == NULL))                                        \
            return REFUSE(inst, "%s: NULL value reference or value array for %zu values", function, \
                          (size_t)(nvr));                                                          \
    } while (0)

#define GET_OR_SET(function, c, vr, nvr, value)                                                    \
    do {                                                                                           \
        fmi2Status refused_;                                                                       \
        Instance *inst_ = enter((c), "fmi2" #function, &refused_);                                 \
        if (inst_ == NULL) return refused_;                                                        \
        CHECK_ARRAYS(inst_, "fmi2" #function, vr, nvr, value);                                     \
        return leave(inst_, inner.function(inst_->component, vr, nvr, value));                     \
    } while (0)

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    GET_OR_SET(GetReal, c, vr, nvr, value);
}
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    GET_OR_SET(GetInteger, c, vr, nvr, value);
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    GET_OR_SET(GetBoolean, c, vr, nvr, value);
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    GET_OR_SET(GetString, c, vr, nvr, value);
}
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    GET_OR_SET(SetReal, c, vr, nvr, value);
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[])
{
    GET_OR_SET(SetInteger, c, vr, nvr, value);
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[])
{
    GET_OR_SET(SetBoolean, c, vr, nvr, value);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[])
{
    fmi2Status refused;
    Instance *inst = enter(c, "fmi2SetString", &refused);
    if (inst == NULL) return refused;
    CHECK_ARRAYS(inst, "fmi2SetString", vr, nvr, value);
    for (size_t i = 0; i < nvr; ++i)
        if (value[i] == NULL)
            return REFUSE(inst, "fmi2SetString: the string for value reference %u is NULL", vr[i]);
    return leave(inst, inner.SetString(inst->component, vr, nvr, value));
}

/* ---- FMU states: only pointers this instance handed out and has not freed are accepted ---- */

static int known_state(Instance *inst, const char *function, fmi2FMUstate state)
{
    if (state == NULL) {
        log_to(&inst->host, inst->name, fmi2Error, "%s: the FMU state is NULL", function);
        return 0;
    }
    if (state_index(inst, state) < 0) {
        log_to(&inst->host, inst->name, fmi2Error,
               "%s: %p is not an FMU state of this instance (never handed out, or freed)", function, state);
        return 0;
    }
    return 1;
}

/* The state slot of Get/DeSerialize: NULL for a new state, or a state of ours to overwrite. */
static int state_slot_ok(Instance *inst, const char *function, fmi2FMUstate *FMUstate)
{
    if (FMUstate == NULL) {
        log_to(&inst->host, inst->name, fmi2Error, "%s: no place to return the FMU state (NULL)", function);
        return 0;
    }
    return *FMUstate == NULL || known_state(inst, function, *FMUstate);
}

/* A state pythonfmu has just made: kept if the call succeeded, else released. */
static fmi2Status take_state(Instance *inst, const char *function, fmi2Status status,
                             fmi2FMUstate made, fmi2FMUstate *FMUstate)
{
    if (status > fmi2Warning || made == NULL) {
        if (made != NULL && !(INNER_RELEASES_ON_FATAL && inst->released))
            inner.FreeFMUstate(inst->component, &made);
        if (status <= fmi2Warning) {
            log_to(&inst->host, inst->name, fmi2Error, "%s: the Python slave returned no state", function);
            status = fmi2Error;
        }
        return status;
    }
    if (!add_state(inst, made)) {
        inner.FreeFMUstate(inst->component, &made);
        log_to(&inst->host, inst->name, fmi2Error, "%s: out of memory", function);
        return fmi2Error;
    }
    if (*FMUstate != NULL) { /* overwriting a state: the old one is released */
        fmi2FMUstate old = *FMUstate;
        remove_state(inst, old);
        inner.FreeFMUstate(inst->component, &old);
    }
    *FMUstate = made;
    return status;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    fmi2Status refused;
    Instance *inst = enter(c, "fmi2GetFMUstate", &refused);
    if (inst == NULL) return refused;
    if (!state_slot_ok(inst, "fmi2GetFMUstate", FMUstate)) return fmi2Error;
    fmi2FMUstate made = NULL;
    fmi2Status status = leave(inst, inner.GetFMUstate(inst->component, &made));
    return take_state(inst, "fmi2GetFMUstate", status, made, FMUstate);
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    fmi2Status refused;
    Instance *inst = enter(c, "fmi2SetFMUstate", &refused);
    if (inst == NULL) return refused;
    if (!known_state(inst, "fmi2SetFMUstate", FMUstate)) return fmi2Error;
    return leave(inst, inner.SetFMUstate(inst->component, FMUstate));
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    fmi2Status refused;
    Instance *inst = enter(c, "fmi2FreeFMUstate", &refused);
    if (inst == NULL) return refused;
    if (FMUstate == NULL) return REFUSE(inst, "fmi2FreeFMUstate: the pointer to the FMU state is NULL");
    if (*FMUstate == NULL) return fmi2OK; /* the standard: a NULL state is ignored */
    if (!known_state(inst, "fmi2FreeFMUstate", *FMUstate)) return fmi2Error;
    remove_state(inst, *FMUstate);
    fmi2Status status = leave(inst, inner.FreeFMUstate(inst->component, FMUstate));
    *FMUstate = NULL;
    return status;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size)
{
    fmi2Status refused;
    Instance *inst = enter(c, "fmi2SerializedFMUstateSize", &refused);
    if (inst == NULL) return refused;
    if (size == NULL) return REFUSE(inst, "fmi2SerializedFMUstateSize: no place to return the size (NULL)");
    if (!known_state(inst, "fmi2SerializedFMUstateSize", FMUstate)) return fmi2Error;
    return leave(inst, inner.SerializedFMUstateSize(inst->component, FMUstate, size));
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size)
{
    fmi2Status refused;
    Instance *inst = enter(c, "fmi2SerializeFMUstate", &refused);
    if (inst == NULL) return refused;
    if (serializedState == NULL) return REFUSE(inst, "fmi2SerializeFMUstate: the byte array is NULL");
    if (!known_state(inst, "fmi2SerializeFMUstate", FMUstate)) return fmi2Error;
    /* pythonfmu copies `size` bytes whatever the serialized length: ask first, so that a wrong
     * size is refused instead of read past the end */
    size_t needed = 0;
    fmi2Status status = leave(inst, inner.SerializedFMUstateSize(inst->component, FMUstate, &needed));
    if (status > fmi2Warning) return status;
    if (size < needed)
        return REFUSE(inst, "fmi2SerializeFMUstate: %zu bytes given, the state serializes to %zu "
                            "(fmi2SerializedFMUstateSize)", size, needed);
    return leave(inst, inner.SerializeFMUstate(inst->component, FMUstate, serializedState, needed));
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate)
{
    fmi2Status refused;
    Instance *inst = enter(c, "fmi2DeSerializeFMUstate", &refused);
    if (inst == NULL) return refused;
    if (size > 0 && serializedState == NULL)
        return REFUSE(inst, "fmi2DeSerializeFMUstate: %zu bytes announced but the array is NULL", size);
    if (!state_slot_ok(inst, "fmi2DeSerializeFMUstate", FMUstate)) return fmi2Error;
    fmi2FMUstate made = NULL;
    fmi2Status status = leave(inst, inner.DeSerializeFMUstate(inst->component, serializedState, size, &made));
    /* the slave logs an error for bytes that are not one of its states: that state is dropped */
    return take_state(inst, "fmi2DeSerializeFMUstate", status, made, FMUstate);
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    FORWARD(GetDirectionalDerivative, c, vUnknown_ref, nUnknown, vKnown_ref, nKnown, dvKnown, dvUnknown);
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    FORWARD(SetRealInputDerivatives, c, vr, nvr, order, value);
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    FORWARD(GetRealOutputDerivatives, c, vr, nvr, order, value);
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    FORWARD(DoStep, c, currentCommunicationPoint, communicationStepSize, noSetFMUStatePriorToCurrentPoint);
}

fmi2Status fmi2CancelStep(fmi2Component c) { FORWARD0(CancelStep, c); }

#define GET_STATUS(function, c, s, value)                                                          \
    do {                                                                                           \
        fmi2Status refused_;                                                                       \
        Instance *inst_ = enter((c), "fmi2" #function, &refused_);                                 \
        if (inst_ == NULL) return refused_;                                                        \
        if ((value) == NULL) return REFUSE(inst_, "fmi2" #function ": no place to return the value (NULL)"); \
        return leave(inst_, inner.function(inst_->component, s, value));                           \
    } while (0)

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    GET_STATUS(GetStatus, c, s, value);
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    GET_STATUS(GetRealStatus, c, s, value);
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    GET_STATUS(GetIntegerStatus, c, s, value);
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    GET_STATUS(GetBooleanStatus, c, s, value);
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    GET_STATUS(GetStringStatus, c, s, value);
}
