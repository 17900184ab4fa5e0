/* A minimal FMI 2.0 co-simulation host in C, for the tests: it drives unzipped FMUs as a non-Python
 * FMI tool does (dlopen, every status checked, no Python in the process unless an FMU brings it). It compiles
 * for Windows too (x86_64-w64-mingw32-gcc; LoadLibrary and GetProcAddress, the FMUs' binaries/win64): the
 * tests run it under Wine on the win64 binaries of standalone FMUs.
 *
 * Usage: fmi2_host INPUT OUTPUT.csv MODE
 *   MODE  run                  initialize the units, step them from the first to the last communication point
 *         state K M            run K steps, save every unit's state (fmi2GetFMUstate, and as bytes with
 *                              fmi2SerializeFMUstate), run M steps, restore (fmi2SetFMUstate), run the same M
 *                              steps again, then restore from the bytes (fmi2DeSerializeFMUstate) and run them
 *                              a third time
 *         reinstantiate R      R rounds of "run" in one process, each from fmi2Instantiate to fmi2FreeInstance
 *         pause K              "run", but after K steps it prints "paused" on stdout and waits for a line on
 *                              stdin before the rest (a test meanwhile kills a process)
 *
 * INPUT is a text file, one item a line ('#' starts a comment line):
 *   steps N            number of communication steps
 *   step H             communication step (s): the points are t_k = k H for k < N, and t_N = stop
 *   stop T             last communication point (s)
 *   unit NAME          starts a unit; the lines below it, up to the next "unit", describe it:
 *   location DIR       the unzipped FMU (DIR/binaries/linux64/<identifier>.so is loaded; on Windows
 *                      DIR/binaries/win64/<identifier>.dll)
 *   identifier ID      CoSimulation modelIdentifier
 *   guid GUID
 *   resources URI      fmuResourceLocation ("file:///.../resources")
 *   output VR NAME     a Real read after initialization and after every step (a CSV column UNIT.NAME)
 *   input VR FROM VR2  a Real input set from output VR2 of unit FROM before each step
 *   fixed VR VALUE     a Real input set to VALUE before each step
 *
 * Units are stepped in the order given, each after setting its inputs from the latest outputs (Gauss-Seidel):
 * with "structure" (inputs from "aero") before "aero" (inputs from "structure"), the structure steps with the
 * aero outputs of t, the aero unit with the structure's outputs of t + h. After initialization, each unit in
 * order gets the inputs whose source unit comes before it (and its fixed inputs), then its outputs are read.
 *
 * OUTPUT.csv: a header "phase,time,UNIT.NAME,..." and one row per communication point, numbers as "%.17g"
 * (exact round trip). Phases: "run"; for "state": "run", "continued", "restored", "deserialized" (each of
 * the last two starts with a row at t_K read right after the restore); for "reinstantiate": "round1", ...
 *
 * Logger messages go to stderr. Any call whose status, or the worst status the unit logged during it, is not
 * fmi2OK stops the host with a message naming the call and exit code 1 (2: bad arguments or input).
 * The binaries stay loaded until the process exits (never dlclose'd), as in a host that does not unload them.
 */
#define _POSIX_C_SOURCE 200809L

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifdef _WIN32
#include <windows.h>
#define BINARY_FOLDER "win64"
#define BINARY_SUFFIX ".dll"
#else
#include <dlfcn.h>
#include <unistd.h>
#define BINARY_FOLDER "linux64"
#define BINARY_SUFFIX ".so"
#endif

#include "fmi2Functions.h"

#define MAX_UNITS 8

typedef struct {
    fmi2ValueReference vr;
    int source;          /* index of the source unit, or -1 for a fixed value */
    size_t output;       /* index in the source unit's outputs (its value reference while reading the input) */
    fmi2Real fixed;
} Input;

typedef struct {
    char *name, *location, *identifier, *guid, *resources;
    size_t n_out, n_in;
    fmi2ValueReference *out_vr;
    char **out_name;
    fmi2Real *out_val;
    Input *in;
    fmi2ValueReference *in_vr;
    fmi2Real *in_val;
    char **in_from;      /* per input: the source unit's name as read (NULL for a fixed value) */

    void *lib;
    fmi2Component c;
    fmi2CallbackFunctions callbacks;
    fmi2Status logged;   /* worst status logged since the last check */
    fmi2FMUstate state;
    fmi2Byte *bytes;
    size_t n_bytes;

    fmi2GetVersionTYPE *GetVersion;
    fmi2InstantiateTYPE *Instantiate;
    fmi2FreeInstanceTYPE *FreeInstance;
    fmi2SetupExperimentTYPE *SetupExperiment;
    fmi2EnterInitializationModeTYPE *EnterInitializationMode;
    fmi2ExitInitializationModeTYPE *ExitInitializationMode;
    fmi2TerminateTYPE *Terminate;
    fmi2GetRealTYPE *GetReal;
    fmi2SetRealTYPE *SetReal;
    fmi2DoStepTYPE *DoStep;
    fmi2GetFMUstateTYPE *GetFMUstate;
    fmi2SetFMUstateTYPE *SetFMUstate;
    fmi2FreeFMUstateTYPE *FreeFMUstate;
    fmi2SerializedFMUstateSizeTYPE *SerializedFMUstateSize;
    fmi2SerializeFMUstateTYPE *SerializeFMUstate;
    fmi2DeSerializeFMUstateTYPE *DeSerializeFMUstate;
} Unit;

static Unit units[MAX_UNITS];
static size_t n_units;
static long n_steps = -1;
static double step = -1.0, stop = -1.0;
static FILE *csv;

static const char *status_name(fmi2Status s)
{
    static const char *names[] = {"fmi2OK", "fmi2Warning", "fmi2Discard", "fmi2Error", "fmi2Fatal", "fmi2Pending"};
    return (s >= fmi2OK && s <= fmi2Pending) ? names[s] : "unknown status";
}

static void die(int code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fputs("fmi2_host: ", stderr);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
    if (csv)
        fflush(csv);
    fflush(stderr);
    _exit(code);   /* not exit(): a half-used FMU's interpreter is not finalized from here */
}

static void *xcalloc(size_t n, size_t size)
{
    void *p = calloc(n ? n : 1, size);
    if (!p)
        die(1, "out of memory");
    return p;
}

/* `p` (holding n items) with room for n + 1 */
static void *grow(void *p, size_t n, size_t size)
{
    p = realloc(p, (n + 1) * size);
    if (!p)
        die(1, "out of memory");
    return p;
}

static char *xstrdup(const char *s)
{
    char *p = strdup(s);
    if (!p)
        die(1, "out of memory");
    return p;
}

/* ---- FMI callbacks ------------------------------------------------------------------------------------ */
static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
                   fmi2String message, ...)
{
    Unit *u = (Unit *)env;
    va_list ap;
    if (u && status > u->logged)
        u->logged = status;
    fprintf(stderr, "[%s] %s %s: ", instance ? instance : "?", status_name(status), category ? category : "");
    va_start(ap, message);
    if (message)
        vfprintf(stderr, message, ap);
    va_end(ap);
    fputc('\n', stderr);
}

/* The worse of the returned status and the worst status logged during the call; stop unless fmi2OK. */
static void check(Unit *u, fmi2Status status, const char *call, double t)
{
    fmi2Status worst = status > u->logged ? status : u->logged;
    u->logged = fmi2OK;
    if (worst != fmi2OK)
        die(1, "%s of unit %s at t = %.17g s: %s (returned %s)", call, u->name, t, status_name(worst),
            status_name(status));
}

/* ---- loading ------------------------------------------------------------------------------------------ */
#ifdef _WIN32
/* The binary at the UTF-8 `path`, its own imports looked for in its folder first; NULL on failure. */
static void *open_binary(const char *path)
{
    wchar_t wide[4096];
    if (!MultiByteToWideChar(CP_UTF8, 0, path, -1, wide, 4096))
        return NULL;
    return (void *)LoadLibraryExW(wide, NULL, LOAD_WITH_ALTERED_SEARCH_PATH);
}

static const char *binary_error(void)
{
    static char text[64];
    snprintf(text, sizeof text, "Windows error %lu", GetLastError());
    return text;
}

static void *binary_symbol(void *lib, const char *name)
{
    return (void *)GetProcAddress((HMODULE)lib, name);
}
#else
static void *open_binary(const char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }
static const char *binary_error(void) { return dlerror(); }
static void *binary_symbol(void *lib, const char *name) { return dlsym(lib, name); }
#endif

static void *symbol(Unit *u, const char *name)
{
    void *p = binary_symbol(u->lib, name);
    if (!p)
        die(1, "unit %s: %s not found in its binary: %s", u->name, name, binary_error());
    return p;
}

#define LOAD(u, fn) (*(void **)(&(u)->fn) = symbol((u), "fmi2" #fn))

static void load(Unit *u)
{
    size_t len = strlen(u->location) + strlen(u->identifier) + 32;
    char *path = xcalloc(len, 1);
    const char *version;
    snprintf(path, len, "%s/binaries/" BINARY_FOLDER "/%s" BINARY_SUFFIX, u->location, u->identifier);
    u->lib = open_binary(path);
    if (!u->lib)
        die(1, "unit %s: cannot load %s: %s", u->name, path, binary_error());
    free(path);
    LOAD(u, GetVersion);
    LOAD(u, Instantiate);
    LOAD(u, FreeInstance);
    LOAD(u, SetupExperiment);
    LOAD(u, EnterInitializationMode);
    LOAD(u, ExitInitializationMode);
    LOAD(u, Terminate);
    LOAD(u, GetReal);
    LOAD(u, SetReal);
    LOAD(u, DoStep);
    LOAD(u, GetFMUstate);
    LOAD(u, SetFMUstate);
    LOAD(u, FreeFMUstate);
    LOAD(u, SerializedFMUstateSize);
    LOAD(u, SerializeFMUstate);
    LOAD(u, DeSerializeFMUstate);
    version = u->GetVersion();
    if (!version || strcmp(version, "2.0") != 0)
        die(1, "unit %s: fmi2GetVersion returned %s, expected 2.0", u->name, version ? version : "NULL");
}

/* ---- the co-simulation -------------------------------------------------------------------------------- */
static double comm_point(long k)
{
    return k == n_steps ? stop : (double)k * step;
}

static void instantiate(Unit *u)
{
    u->callbacks.logger = logger;
    u->callbacks.allocateMemory = calloc;
    u->callbacks.freeMemory = free;
    u->callbacks.stepFinished = NULL;
    u->callbacks.componentEnvironment = u;
    u->logged = fmi2OK;
    u->c = u->Instantiate(u->name, fmi2CoSimulation, u->guid, u->resources, &u->callbacks, fmi2False, fmi2True);
    if (!u->c)
        die(1, "fmi2Instantiate of unit %s returned NULL", u->name);
    check(u, fmi2OK, "fmi2Instantiate", 0.0);
    check(u, u->SetupExperiment(u->c, fmi2False, 0.0, 0.0, fmi2False, 0.0), "fmi2SetupExperiment", 0.0);
    check(u, u->EnterInitializationMode(u->c), "fmi2EnterInitializationMode", 0.0);
    check(u, u->ExitInitializationMode(u->c), "fmi2ExitInitializationMode", 0.0);
}

static void finish(Unit *u, double t)
{
    check(u, u->Terminate(u->c), "fmi2Terminate", t);
    u->FreeInstance(u->c);
    check(u, fmi2OK, "fmi2FreeInstance", t);
    u->c = NULL;
}

static void read_outputs(Unit *u, double t)
{
    check(u, u->GetReal(u->c, u->out_vr, u->n_out, u->out_val), "fmi2GetReal", t);
}

/* Inputs from their sources; with `before` >= 0 only those from units earlier than `before` (and fixed). */
static void set_inputs(Unit *u, double t, long before)
{
    size_t i, n = 0;
    for (i = 0; i < u->n_in; i++) {
        const Input *in = &u->in[i];
        if (in->source >= 0 && before >= 0 && in->source >= before)
            continue;
        u->in_vr[n] = in->vr;
        u->in_val[n++] = in->source < 0 ? in->fixed : units[in->source].out_val[in->output];
    }
    if (n)
        check(u, u->SetReal(u->c, u->in_vr, n, u->in_val), "fmi2SetReal", t);
}

static void write_header(void)
{
    size_t i, j;
    fputs("phase,time", csv);
    for (i = 0; i < n_units; i++)
        for (j = 0; j < units[i].n_out; j++)
            fprintf(csv, ",%s.%s", units[i].name, units[i].out_name[j]);
    fputc('\n', csv);
}

static void write_row(const char *phase, double t)
{
    size_t i, j;
    fprintf(csv, "%s,%.17g", phase, t);
    for (i = 0; i < n_units; i++)
        for (j = 0; j < units[i].n_out; j++)
            fprintf(csv, ",%.17g", units[i].out_val[j]);
    fputc('\n', csv);
}

static void start(const char *phase)
{
    size_t i;
    for (i = 0; i < n_units; i++)
        instantiate(&units[i]);
    for (i = 0; i < n_units; i++) {
        set_inputs(&units[i], 0.0, (long)i);
        read_outputs(&units[i], 0.0);
    }
    write_row(phase, comm_point(0));
}

/* Communication steps k = first + 1 .. last, a row after each. */
static void run_steps(long first, long last, const char *phase)
{
    long k;
    size_t i;
    for (k = first + 1; k <= last; k++) {
        double t0 = comm_point(k - 1), t1 = comm_point(k);
        for (i = 0; i < n_units; i++) {
            Unit *u = &units[i];
            set_inputs(u, t0, -1);
            check(u, u->DoStep(u->c, t0, t1 - t0, fmi2False), "fmi2DoStep", t0);
            read_outputs(u, t1);
        }
        write_row(phase, t1);
    }
}

static void finish_all(double t)
{
    size_t i;
    for (i = 0; i < n_units; i++)
        finish(&units[i], t);
}

static void scenario_state(long k, long m)
{
    size_t i;
    double tk = comm_point(k);
    if (k < 0 || m < 1 || k + m > n_steps)
        die(2, "state K M needs 0 <= K, 1 <= M and K + M <= steps (%ld)", n_steps);
    start("run");
    run_steps(0, k, "run");
    for (i = 0; i < n_units; i++) {
        Unit *u = &units[i];
        u->state = NULL;
        check(u, u->GetFMUstate(u->c, &u->state), "fmi2GetFMUstate", tk);
        check(u, u->SerializedFMUstateSize(u->c, u->state, &u->n_bytes), "fmi2SerializedFMUstateSize", tk);
        u->bytes = xcalloc(u->n_bytes, 1);
        check(u, u->SerializeFMUstate(u->c, u->state, u->bytes, u->n_bytes), "fmi2SerializeFMUstate", tk);
    }
    run_steps(k, k + m, "continued");
    for (i = 0; i < n_units; i++)
        check(&units[i], units[i].SetFMUstate(units[i].c, units[i].state), "fmi2SetFMUstate", tk);
    for (i = 0; i < n_units; i++)
        read_outputs(&units[i], tk);
    write_row("restored", tk);
    run_steps(k, k + m, "restored");
    for (i = 0; i < n_units; i++) {   /* the bytes must restore on their own: the state is gone */
        Unit *u = &units[i];
        check(u, u->FreeFMUstate(u->c, &u->state), "fmi2FreeFMUstate", tk);
        check(u, u->DeSerializeFMUstate(u->c, u->bytes, u->n_bytes, &u->state), "fmi2DeSerializeFMUstate", tk);
        check(u, u->SetFMUstate(u->c, u->state), "fmi2SetFMUstate", tk);
    }
    for (i = 0; i < n_units; i++)
        read_outputs(&units[i], tk);
    write_row("deserialized", tk);
    run_steps(k, k + m, "deserialized");
    for (i = 0; i < n_units; i++) {
        Unit *u = &units[i];
        check(u, u->FreeFMUstate(u->c, &u->state), "fmi2FreeFMUstate", comm_point(k + m));
        free(u->bytes);
        u->bytes = NULL;
    }
    finish_all(comm_point(k + m));
}

/* ---- the input file ----------------------------------------------------------------------------------- */
/* One line of `f` into *line (grown as needed, without its end); -1 at the end of the file. (getline is POSIX,
 * and Windows's C library has none.) */
static long read_line(char **line, size_t *cap, FILE *f)
{
    size_t n = 0;
    int c;
    while ((c = fgetc(f)) != EOF && c != '\n') {
        if (n + 2 > *cap) {
            *cap = *cap ? 2 * *cap : 256;
            *line = realloc(*line, *cap);
            if (!*line)
                die(1, "out of memory");
        }
        (*line)[n++] = (char)c;
    }
    if (c == EOF && n == 0)
        return -1;
    if (!*line) {
        *cap = 1;
        *line = xcalloc(1, 1);
    }
    (*line)[n] = '\0';
    return (long)n;
}

static fmi2ValueReference parse_vr(const char *s, long line)
{
    char *end;
    unsigned long v = strtoul(s, &end, 10);
    if (end == s || v > 0xffffffffUL)
        die(2, "line %ld: %s is not a value reference", line, s);
    return (fmi2ValueReference)v;
}

static double parse_real(const char *s, long line)
{
    char *end;
    double v = strtod(s, &end);
    if (end == s || (*end && *end != ' ' && *end != '\t'))
        die(2, "line %ld: %s is not a number", line, s);
    return v;
}

static void read_input(const char *path)
{
    FILE *f = fopen(path, "r");
    char *line = NULL, *key, *rest;
    size_t cap = 0, i, j;
    long number = 0;
    Unit *u = NULL;
    if (!f)
        die(2, "cannot open %s", path);
    while (read_line(&line, &cap, f) >= 0) {
        number++;
        line[strcspn(line, "\r\n")] = '\0';
        key = line + strspn(line, " \t");
        if (!*key || *key == '#')
            continue;
        rest = key + strcspn(key, " \t");
        if (*rest)
            *rest++ = '\0';
        rest += strspn(rest, " \t");
        if (!strcmp(key, "steps")) {
            n_steps = (long)parse_real(rest, number);
        } else if (!strcmp(key, "step")) {
            step = parse_real(rest, number);
        } else if (!strcmp(key, "stop")) {
            stop = parse_real(rest, number);
        } else if (!strcmp(key, "unit")) {
            if (n_units == MAX_UNITS)
                die(2, "line %ld: at most %d units", number, MAX_UNITS);
            u = &units[n_units++];
            u->name = xstrdup(rest);
        } else if (!u) {
            die(2, "line %ld: %s before the first unit line", number, key);
        } else if (!strcmp(key, "location")) {
            u->location = xstrdup(rest);
        } else if (!strcmp(key, "identifier")) {
            u->identifier = xstrdup(rest);
        } else if (!strcmp(key, "guid")) {
            u->guid = xstrdup(rest);
        } else if (!strcmp(key, "resources")) {
            u->resources = xstrdup(rest);
        } else if (!strcmp(key, "output") || !strcmp(key, "input") || !strcmp(key, "fixed")) {
            char *a = strtok(rest, " \t"), *b = strtok(NULL, " \t"), *c = strtok(NULL, " \t");
            if (!a || !b || (!strcmp(key, "input") && !c))
                die(2, "line %ld: %s needs %s", number, key,
                    !strcmp(key, "input") ? "VR FROM VR2" : !strcmp(key, "output") ? "VR NAME" : "VR VALUE");
            if (!strcmp(key, "output")) {
                u->out_vr = grow(u->out_vr, u->n_out, sizeof *u->out_vr);
                u->out_name = grow(u->out_name, u->n_out, sizeof *u->out_name);
                u->out_vr[u->n_out] = parse_vr(a, number);
                u->out_name[u->n_out++] = xstrdup(b);
            } else {
                u->in = grow(u->in, u->n_in, sizeof *u->in);
                u->in_from = grow(u->in_from, u->n_in, sizeof *u->in_from);
                u->in[u->n_in].vr = parse_vr(a, number);
                if (!strcmp(key, "input")) {
                    u->in_from[u->n_in] = xstrdup(b);
                    u->in[u->n_in].output = parse_vr(c, number);   /* the source's VR until resolved */
                } else {
                    u->in_from[u->n_in] = NULL;
                    u->in[u->n_in].source = -1;
                    u->in[u->n_in].fixed = parse_real(b, number);
                }
                u->n_in++;
            }
        } else {
            die(2, "line %ld: unknown item %s", number, key);
        }
    }
    free(line);
    fclose(f);
    if (n_units == 0 || n_steps < 1 || !(step > 0.0) || !(stop > 0.0))
        die(2, "%s: needs steps >= 1, step > 0, stop > 0 and at least one unit", path);
    for (i = 0; i < n_units; i++) {
        u = &units[i];
        if (!u->location || !u->identifier || !u->guid || !u->resources)
            die(2, "unit %s: location, identifier, guid and resources are all needed", u->name);
        u->out_val = xcalloc(u->n_out, sizeof *u->out_val);
        u->in_vr = xcalloc(u->n_in, sizeof *u->in_vr);
        u->in_val = xcalloc(u->n_in, sizeof *u->in_val);
        for (j = 0; j < u->n_in; j++) {
            size_t s, o;
            if (!u->in_from[j])
                continue;
            for (s = 0; s < n_units && strcmp(units[s].name, u->in_from[j]); s++)
                ;
            if (s == n_units)
                die(2, "unit %s: input %u from unknown unit %s", u->name, u->in[j].vr, u->in_from[j]);
            for (o = 0; o < units[s].n_out && units[s].out_vr[o] != u->in[j].output; o++)
                ;
            if (o == units[s].n_out)
                die(2, "unit %s: input %u from %s %lu, which is not one of its outputs", u->name, u->in[j].vr,
                    u->in_from[j], (unsigned long)u->in[j].output);
            u->in[j].source = (int)s;
            u->in[j].output = o;
        }
    }
}

int main(int argc, char **argv)
{
    size_t i;
    if (argc < 4)
        die(2, "usage: fmi2_host INPUT OUTPUT.csv run | state K M | reinstantiate R | pause K");
    read_input(argv[1]);
    csv = fopen(argv[2], "w");
    if (!csv)
        die(2, "cannot write %s", argv[2]);
    for (i = 0; i < n_units; i++)
        load(&units[i]);
    write_header();
    if (!strcmp(argv[3], "run") && argc == 4) {
        start("run");
        run_steps(0, n_steps, "run");
        finish_all(comm_point(n_steps));
    } else if (!strcmp(argv[3], "pause") && argc == 5) {
        long k = atol(argv[4]);
        char *answer = NULL;
        size_t cap = 0;
        if (k < 0 || k > n_steps)
            die(2, "pause K needs 0 <= K <= steps (%ld)", n_steps);
        start("run");
        run_steps(0, k, "run");
        fflush(csv);
        printf("paused\n");
        fflush(stdout);
        read_line(&answer, &cap, stdin);
        free(answer);
        run_steps(k, n_steps, "run");
        finish_all(comm_point(n_steps));
    } else if (!strcmp(argv[3], "state") && argc == 6) {
        scenario_state(atol(argv[4]), atol(argv[5]));
    } else if (!strcmp(argv[3], "reinstantiate") && argc == 5) {
        long r, rounds = atol(argv[4]);
        char phase[32];
        if (rounds < 1)
            die(2, "reinstantiate R needs R >= 1");
        for (r = 1; r <= rounds; r++) {
            snprintf(phase, sizeof phase, "round%ld", r);
            start(phase);
            run_steps(0, n_steps, phase);
            finish_all(comm_point(n_steps));
        }
    } else {
        die(2, "unknown mode; usage: fmi2_host INPUT OUTPUT.csv run | state K M | reinstantiate R | pause K");
    }
    if (fclose(csv) != 0)
        die(1, "writing %s failed", argv[2]);
    return 0;
}
