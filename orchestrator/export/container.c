/* The binary of wing.fmu: the structure and aero FMUs coupled inside one FMI 2.0 co-simulation FMU.
 *
 * `wingsim export` (orchestrator/export/container.py) compiles this file into binaries/linux64/<id>.so of
 * wing.fmu and unpacks each unit FMU whole into the container's resources, as resources/<unit>/. At
 * fmi2Instantiate the container reads its configuration (resources/container.txt, format below), loads
 * each unit's binary resources/<unit>/binaries/linux64/<modelIdentifier>.so (dlopen, RTLD_LOCAL) and
 * instantiates it with the host's callbacks, its logger wrapped so that every message of a unit reaches
 * the host prefixed with the unit's name. It assumes nothing of the units beyond the FMI 2.0 standard.
 *
 * Coupling, as `coupling.algorithm = "jacobi"` of `wingsim run`: at fmi2ExitInitializationMode the
 * connections are copied once (the structure's initial e, de to the aero unit, the aero unit's initial
 * Q to the structure). fmi2DoStep(t, H) accepts any finite H > 0: it takes internal steps of the
 * configured `step` from t, the last one ending exactly at t + H (a remainder within STEP_SLACK of a
 * whole step is taken with the last step rather than as a sliver of its own). In each internal step every
 * unit steps from the same inputs, then every connection is copied (all outputs read before any input is
 * set). The container cannot save or restore its state (canGetAndSetFMUstate is false).
 *
 * Variables: the host sees Reals only. Value reference 0 is `time`, answered by the container; every
 * other one is a unit's output or parameter, forwarded to the unit (parameters only before
 * fmi2ExitInitializationMode). Integer, Boolean and String access is refused.
 *
 * Statuses: every unit call's status is checked. A unit returning fmi2Discard or fmi2Error (or NULL from
 * fmi2Instantiate) makes the container call return fmi2Error, fmi2Fatal makes it return fmi2Fatal; the
 * container logs which unit failed in which call, after the unit's own message. After a failure in a
 * call that moves the units on (initialization, a step, terminate, reset) the container refuses to step
 * until fmi2Reset; after fmi2Fatal it refuses everything but fmi2FreeInstance and never calls the unit
 * that returned it again (the standard forbids it). A NULL or foreign component gives fmi2Error. Nothing
 * here aborts or exits the process.
 *
 * The configuration file: plain text, one record a line, words separated by spaces; empty lines and
 * lines starting with '#' are skipped. The last field of `guid`, `unit` and `variable` is the rest of the
 * line (it may hold spaces). Value references are decimal.
 *
 *   wingsim-container 1                 first record: the format and its version
 *   guid GUID                           the container's GUID (as in its modelDescription.xml)
 *   step H                              internal step (s), the scene's coupling.step
 *   unit NAME MODEL_IDENTIFIER GUID     a unit, unpacked in resources/NAME/; units are instantiated and
 *                                       stepped in this order
 *   connection FROM TO N F1..FN T1..TN  output value references F1..FN of unit FROM are copied to inputs
 *                                       T1..TN of unit TO (one block, one fmi2GetReal and one fmi2SetReal)
 *   variable VR KIND UNIT UVR NAME      container value reference VR (> 0) is unit UNIT's value reference
 *                                       UVR; KIND is `output` or `parameter`; NAME is for messages
 *   start VR VALUE                      the parameter VR (declared above) starts at VALUE: it is set on its
 *                                       unit after fmi2Instantiate and after fmi2Reset, so that the units run
 *                                       the container's start values whatever values they were built with
 *
 * C99 and POSIX; links only libdl (and -pthread for the lock of the instance list).
 */
#define _POSIX_C_SOURCE 200809L

#include <dlfcn.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2_table.h"
#include "fmi2_uri.h"

#define CONFIG_FILE "container.txt"
#define FORMAT_LINE "wingsim-container 1"
#define PLATFORM "linux64"
#define TIME_TOLERANCE 1e-9 /* relative to max(1 s, |t|): the units' own tolerance on a communication point */
#define STEP_SLACK 1e-9     /* relative to the internal step: a shorter remainder joins the last step */
#define MAX_VARIABLES 10000000
#define CATEGORY_ERROR "logStatusError"
#define CATEGORY_WARNING "logStatusWarning"
#define CATEGORY_FATAL "logStatusFatal"

/* ------------------------------------------------------------------------------------------------ */
/* The model */

struct Container;

typedef struct {
    char *name, *identifier, *guid;
    struct Container *owner;
    void *library;
    Fmi2Table fmi;
    fmi2CallbackFunctions callbacks; /* the host's, with unit_logger and this unit as environment */
    fmi2Component component;
    int fatal;                       /* it returned fmi2Fatal: never called again */
} Unit;

typedef struct {
    size_t from, to, n;              /* unit indices; number of values */
    fmi2ValueReference *from_vr, *to_vr;
    fmi2Real *values;
} Block;

typedef enum { UNUSED = 0, TIME, OUTPUT, PARAMETER } Kind;

typedef struct {
    Kind kind;
    size_t unit;
    fmi2ValueReference unit_vr;
    char *name;
    int has_start;                   /* a parameter with a start value of the container's own */
    fmi2Real start;
} Variable;

typedef enum { INSTANTIATED, INITIALIZATION, STEPPING, TERMINATED } Phase;

typedef struct Container {
    struct Container *next;          /* list of live instances: a foreign pointer is refused */
    char *name;
    fmi2CallbackFunctions host;
    char *guid;
    double step;
    size_t n_units, n_blocks, n_variables;
    Unit *units;
    Block *blocks;
    Variable *variables;             /* indexed by value reference */
    Phase phase;
    double time;
    int failed;                      /* a unit failed in a call that moves the units on */
    int dead;                        /* a unit returned fmi2Fatal */
    char failure[1024];              /* what failed, for later refusals */
    size_t scratch_size;             /* buffers of the calls forwarded to a unit */
    fmi2ValueReference *scratch_vr;
    size_t *scratch_index;
    fmi2Real *scratch_value;
} Container;

static pthread_mutex_t instances_lock = PTHREAD_MUTEX_INITIALIZER;
static Container *instances = NULL;

/* ------------------------------------------------------------------------------------------------ */
/* Text and logging */

/* A newly allocated printf-formatted string, NULL if out of memory. */
static char *vformat(const char *format, va_list args)
{
    va_list copy;
    va_copy(copy, args);
    int n = vsnprintf(NULL, 0, format, copy);
    va_end(copy);
    if (n < 0) return NULL;
    char *text = malloc((size_t)n + 1);
    if (text != NULL) vsnprintf(text, (size_t)n + 1, format, args);
    return text;
}

static char *formatted(const char *format, ...)
{
    va_list args;
    va_start(args, format);
    char *text = vformat(format, args);
    va_end(args);
    return text;
}

/* Pass `text` to the host's logger as its printf format (the standard's convention): '%' doubled. */
static void log_text(const Container *c, fmi2Status status, const char *category, const char *text)
{
    if (c->host.logger == NULL || text == NULL) return;
    char *escaped = malloc(2 * strlen(text) + 1);
    if (escaped == NULL) return;
    char *out = escaped;
    for (const char *p = text; *p != '\0'; ++p) {
        if (*p == '%') *out++ = '%';
        *out++ = *p;
    }
    *out = '\0';
    if (category == NULL)
        category = status >= fmi2Fatal   ? CATEGORY_FATAL
                   : status >= fmi2Error ? CATEGORY_ERROR
                                         : CATEGORY_WARNING;
    c->host.logger(c->host.componentEnvironment, c->name, status, category, escaped);
    free(escaped);
}

static void vsay(const Container *c, fmi2Status status, const char *format, va_list args)
{
    char *text = vformat(format, args);
    log_text(c, status, NULL, text != NULL ? text : format);
    free(text);
}

static void say(const Container *c, fmi2Status status, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    vsay(c, status, format, args);
    va_end(args);
}

/* Log a refusal of the container itself and return fmi2Error. */
static fmi2Status refuse(const Container *c, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    vsay(c, fmi2Error, format, args);
    va_end(args);
    return fmi2Error;
}

/* The logger the units call: their message, formatted with its arguments, prefixed with the unit's name. */
static void unit_logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                        fmi2String category, fmi2String message, ...)
{
    (void)instance;
    Unit *u = (Unit *)env;
    if (u == NULL || message == NULL) return;
    va_list args;
    va_start(args, message);
    char *text = vformat(message, args);
    va_end(args);
    char *prefixed = formatted("%s: %s", u->name, text != NULL ? text : message);
    log_text(u->owner, status, category, prefixed != NULL ? prefixed : message);
    free(prefixed);
    free(text);
}

static const char *status_name(fmi2Status s)
{
    static const char *names[] = {"fmi2OK",    "fmi2Warning", "fmi2Discard",
                                  "fmi2Error", "fmi2Fatal",   "fmi2Pending"};
    return (unsigned)s < sizeof names / sizeof names[0] ? names[s] : "an unknown status";
}

static fmi2Status worse(fmi2Status a, fmi2Status b) { return a > b ? a : b; }

/* The container's status for a unit's call that returned `s`: fmi2OK and fmi2Warning pass; fmi2Discard,
 * fmi2Error and anything unknown (fmi2Pending: the container makes no asynchronous calls) are fmi2Error,
 * fmi2Fatal is fmi2Fatal. A failure is logged, naming the unit and the call (`format`), and kept in
 * c->failure. */
static fmi2Status checked(Container *c, Unit *u, fmi2Status s, const char *format, ...)
{
    if (s == fmi2OK || s == fmi2Warning) return s;
    va_list args;
    va_start(args, format);
    char *call = vformat(format, args);
    va_end(args);
    fmi2Status result = s == fmi2Fatal ? fmi2Fatal : fmi2Error;
    snprintf(c->failure, sizeof c->failure, "unit %s: %s returned %s", u->name, call != NULL ? call : format,
             status_name(s));
    free(call);
    if (result == fmi2Fatal) {
        u->fatal = 1;
        c->dead = 1;
    }
    say(c, result, "%s%s", c->failure,
        result == fmi2Fatal ? ": the container cannot be used any more (fmi2FreeInstance)" : "");
    return result;
}

/* ------------------------------------------------------------------------------------------------ */
/* The configuration file */

typedef struct {
    Container *c;
    const char *path;
    long number;   /* line number */
    char *cursor;  /* what is left of the line */
} Line;

/* The next word of the line (NUL-terminated in place), NULL at its end. */
static char *word(Line *line)
{
    char *p = line->cursor;
    while (*p == ' ' || *p == '\t') ++p;
    if (*p == '\0') return NULL;
    char *start = p;
    while (*p != '\0' && *p != ' ' && *p != '\t') ++p;
    if (*p != '\0') *p++ = '\0';
    line->cursor = p;
    return start;
}

/* The rest of the line without its surrounding blanks, NULL if nothing is left. */
static char *rest(Line *line)
{
    char *p = line->cursor;
    while (*p == ' ' || *p == '\t') ++p;
    char *end = p + strlen(p);
    while (end > p && (end[-1] == ' ' || end[-1] == '\t')) --end;
    *end = '\0';
    line->cursor = end;
    return *p != '\0' ? p : NULL;
}

static int bad(const Line *line, const char *what)
{
    say(line->c, fmi2Error, "fmi2Instantiate: %s line %ld: %s", line->path, line->number, what);
    return 0;
}

static int read_size(Line *line, size_t *value)
{
    char *w = word(line), *end;
    if (w == NULL || *w < '0' || *w > '9') return 0;
    unsigned long long v = strtoull(w, &end, 10);
    *value = (size_t)v;
    return *end == '\0' && (unsigned long long)*value == v;
}

static int read_vr(Line *line, fmi2ValueReference *vr)
{
    size_t v;
    if (!read_size(line, &v) || v != (fmi2ValueReference)v) return 0;
    *vr = (fmi2ValueReference)v;
    return 1;
}

static int read_unit_name(Line *line, size_t *index)
{
    const char *name = word(line);
    for (size_t i = 0; name != NULL && i < line->c->n_units; ++i) {
        if (strcmp(line->c->units[i].name, name) == 0) {
            *index = i;
            return 1;
        }
    }
    return 0;
}

static int parse_unit(Line *line)
{
    Container *c = line->c;
    char *name = word(line), *identifier = word(line), *guid = rest(line);
    if (guid == NULL) return bad(line, "expected: unit NAME MODEL_IDENTIFIER GUID");
    if (strchr(name, '/') != NULL || strcmp(name, ".") == 0 || strcmp(name, "..") == 0)
        return bad(line, "a unit's name is the name of its folder in resources/");
    for (size_t i = 0; i < c->n_units; ++i)
        if (strcmp(c->units[i].name, name) == 0) return bad(line, "this unit is declared twice");
    Unit *units = realloc(c->units, (c->n_units + 1) * sizeof *units);
    if (units == NULL) return bad(line, "out of memory");
    c->units = units;
    Unit *u = &units[c->n_units];
    memset(u, 0, sizeof *u);
    u->owner = c;
    u->name = strdup(name);
    u->identifier = strdup(identifier);
    u->guid = strdup(guid);
    c->n_units++; /* counted now, so that a failure below still frees what was copied */
    if (u->name == NULL || u->identifier == NULL || u->guid == NULL) return bad(line, "out of memory");
    return 1;
}

static int parse_connection(Line *line)
{
    Container *c = line->c;
    Block b = {0};
    if (!read_unit_name(line, &b.from) || !read_unit_name(line, &b.to) || !read_size(line, &b.n) || b.n == 0
        || b.n > MAX_VARIABLES)
        return bad(line, "expected: connection FROM TO N F1..FN T1..TN (FROM and TO units declared above)");
    Block *blocks = realloc(c->blocks, (c->n_blocks + 1) * sizeof *blocks);
    if (blocks == NULL) return bad(line, "out of memory");
    c->blocks = blocks;
    b.from_vr = calloc(b.n, sizeof *b.from_vr);
    b.to_vr = calloc(b.n, sizeof *b.to_vr);
    b.values = calloc(b.n, sizeof *b.values);
    c->blocks[c->n_blocks++] = b;
    if (b.from_vr == NULL || b.to_vr == NULL || b.values == NULL) return bad(line, "out of memory");
    for (size_t i = 0; i < b.n; ++i)
        if (!read_vr(line, &b.from_vr[i])) return bad(line, "expected N value references of FROM");
    for (size_t i = 0; i < b.n; ++i)
        if (!read_vr(line, &b.to_vr[i])) return bad(line, "expected N value references of TO");
    if (word(line) != NULL) return bad(line, "more than 2 N value references");
    return 1;
}

static int parse_variable(Line *line)
{
    Container *c = line->c;
    fmi2ValueReference vr, unit_vr;
    size_t unit;
    const char *kind = NULL;
    if (!read_vr(line, &vr) || (kind = word(line)) == NULL || !read_unit_name(line, &unit)
        || !read_vr(line, &unit_vr))
        return bad(line, "expected: variable VR output|parameter UNIT UVR NAME (UNIT declared above)");
    const char *name = rest(line);
    Kind k = strcmp(kind, "output") == 0 ? OUTPUT : strcmp(kind, "parameter") == 0 ? PARAMETER : UNUSED;
    if (k == UNUSED || name == NULL) return bad(line, "a variable is an output or a parameter, with a name");
    if (vr == 0 || vr >= MAX_VARIABLES) return bad(line, "value reference 0 is time; others are 1..10^7");
    if (vr >= c->n_variables) {
        Variable *variables = realloc(c->variables, ((size_t)vr + 1) * sizeof *variables);
        if (variables == NULL) return bad(line, "out of memory");
        memset(variables + c->n_variables, 0, ((size_t)vr + 1 - c->n_variables) * sizeof *variables);
        c->variables = variables;
        c->n_variables = (size_t)vr + 1;
    }
    Variable *v = &c->variables[vr];
    if (v->kind != UNUSED) return bad(line, "this value reference is declared twice");
    v->name = strdup(name);
    if (v->name == NULL) return bad(line, "out of memory");
    v->kind = k;
    v->unit = unit;
    v->unit_vr = unit_vr;
    return 1;
}

static int parse_start(Line *line)
{
    Container *c = line->c;
    fmi2ValueReference vr;
    const char *w = NULL;
    char *end = NULL;
    if (!read_vr(line, &vr) || (w = word(line)) == NULL) return bad(line, "expected: start VR VALUE");
    double value = strtod(w, &end);
    if (*end != '\0' || !(value > -1e308 && value < 1e308) || word(line) != NULL)
        return bad(line, "expected: start VR VALUE, a finite number");
    if (vr >= c->n_variables || c->variables[vr].kind != PARAMETER)
        return bad(line, "start: VR is not a parameter declared above");
    c->variables[vr].has_start = 1;
    c->variables[vr].start = value;
    return 1;
}

/* Set every parameter that has a start value on its unit; `call` names the container call, for messages. */
static fmi2Status apply_starts(Container *c, const char *call)
{
    fmi2Status status = fmi2OK;
    for (size_t vr = 0; vr < c->n_variables && status <= fmi2Warning; ++vr) {
        Variable *v = &c->variables[vr];
        if (!v->has_start) continue;
        Unit *u = &c->units[v->unit];
        status = worse(status, checked(c, u, u->fmi.SetReal(u->component, &v->unit_vr, 1, &v->start),
                                       "fmi2SetReal of the start value of %s in %s", v->name, call));
    }
    return status;
}

static int parse_line(Line *line)
{
    const char *record = word(line);
    if (strcmp(record, "guid") == 0) {
        const char *guid = rest(line);
        if (guid == NULL) return bad(line, "expected: guid GUID");
        free(line->c->guid);
        return (line->c->guid = strdup(guid)) != NULL || bad(line, "out of memory");
    }
    if (strcmp(record, "step") == 0) {
        const char *w = word(line);
        char *end = NULL;
        double h = w != NULL ? strtod(w, &end) : 0.0;
        if (w == NULL || *end != '\0' || !(h > 0.0 && h < 1e300) || word(line) != NULL)
            return bad(line, "expected: step H, a finite number of seconds > 0");
        line->c->step = h;
        return 1;
    }
    if (strcmp(record, "unit") == 0) return parse_unit(line);
    if (strcmp(record, "connection") == 0) return parse_connection(line);
    if (strcmp(record, "variable") == 0) return parse_variable(line);
    if (strcmp(record, "start") == 0) return parse_start(line);
    return bad(line, "unknown record (expected guid, step, unit, connection, variable or start)");
}

/* Read resources/container.txt into `c`; 0 (the reason logged) if it is missing or wrong. */
static int read_config(Container *c, const char *resources)
{
    char *path = formatted("%s/%s", resources, CONFIG_FILE);
    FILE *file = path != NULL ? fopen(path, "r") : NULL;
    if (file == NULL) {
        say(c, fmi2Error, "fmi2Instantiate: cannot read the container's configuration %s",
            path != NULL ? path : CONFIG_FILE);
        free(path);
        return 0;
    }
    Line line = {c, path, 0, NULL};
    char *text = NULL;
    size_t capacity = 0;
    int ok = 1, versioned = 0;
    while (ok && getline(&text, &capacity, file) != -1) {
        line.number++;
        text[strcspn(text, "\r\n")] = '\0';
        line.cursor = text;
        char *content = rest(&line);
        if (content == NULL || content[0] == '#') continue;
        if (!versioned) {
            ok = strcmp(content, FORMAT_LINE) == 0
                 || bad(&line, "the first record must be \"" FORMAT_LINE "\"");
            versioned = 1;
            continue;
        }
        line.cursor = content;
        ok = parse_line(&line);
    }
    free(text);
    fclose(file);
    if (ok && (c->guid == NULL || c->step <= 0.0 || c->n_units == 0)) {
        say(c, fmi2Error, "fmi2Instantiate: %s lacks a guid, a step or a unit", path);
        ok = 0;
    }
    free(path);
    return ok;
}

/* ------------------------------------------------------------------------------------------------ */
/* Resource locations */

/* "file://" + `path`, every byte but unreserved characters and '/' percent-encoded (RFC 3986), so that any
 * unit reads it, whatever the folder's name. */
static char *path_to_uri(const char *path)
{
    static const char hex[] = "0123456789ABCDEF";
    char *uri = malloc(strlen("file://") + 3 * strlen(path) + 1);
    if (uri == NULL) return NULL;
    char *out = uri + sprintf(uri, "file://");
    for (const unsigned char *p = (const unsigned char *)path; *p != '\0'; ++p) {
        if ((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') || (*p >= '0' && *p <= '9')
            || strchr("-._~/", *p) != NULL) {
            *out++ = (char)*p;
        } else {
            *out++ = '%';
            *out++ = hex[*p >> 4];
            *out++ = hex[*p & 15];
        }
    }
    *out = '\0';
    return uri;
}

/* ------------------------------------------------------------------------------------------------ */
/* Units */

static int resolve(Unit *u, const char *path)
{
    const char *missing = fmi2_table_resolve(u->library, &u->fmi);
    if (missing != NULL)
        say(u->owner, fmi2Error, "fmi2Instantiate: unit %s: %s has no function %s", u->name, path, missing);
    return missing == NULL;
}

/* Load the unit's binary and instantiate it; 0 (the reason logged) on failure. */
static int start_unit(Unit *u, const char *resources, fmi2Boolean logging_on)
{
    char *path = formatted("%s/%s/binaries/" PLATFORM "/%s.so", resources, u->name, u->identifier);
    char *unit_resources = formatted("%s/%s/resources", resources, u->name);
    char *uri = unit_resources != NULL ? path_to_uri(unit_resources) : NULL;
    int ok = 0;
    if (path == NULL || uri == NULL) {
        say(u->owner, fmi2Error, "fmi2Instantiate: out of memory");
    } else if ((u->library = dlopen(path, RTLD_NOW | RTLD_LOCAL)) == NULL) {
        /* RTLD_LOCAL: every unit exports the same fmi2 names, and each must keep its own */
        const char *why = dlerror();
        say(u->owner, fmi2Error, "fmi2Instantiate: unit %s: cannot load %s: %s", u->name, path,
            why != NULL ? why : "dlopen failed");
    } else if (resolve(u, path)) {
        fmi2CallbackFunctions callbacks = {unit_logger, u->owner->host.allocateMemory,
                                           u->owner->host.freeMemory, NULL, u};
        memcpy(&u->callbacks, &callbacks, sizeof callbacks);
        u->component = u->fmi.Instantiate(u->name, fmi2CoSimulation, u->guid, uri, &u->callbacks, fmi2False,
                                          logging_on);
        ok = u->component != NULL;
        if (!ok)
            say(u->owner, fmi2Error, "unit %s: fmi2Instantiate returned NULL (the unit's messages above say "
                "why)", u->name);
    }
    free(uri);
    free(unit_resources);
    free(path);
    return ok;
}

/* Free the unit's instance and unload its binary; a unit that returned fmi2Fatal is left alone. */
static void stop_unit(Unit *u)
{
    if (u->fatal) return;
    if (u->component != NULL) u->fmi.FreeInstance(u->component);
    u->component = NULL;
    if (u->library != NULL) dlclose(u->library);
    u->library = NULL;
}

/* Everything of the container: its units stopped, its memory freed. */
static void destroy(Container *c)
{
    for (size_t i = 0; i < c->n_units; ++i) {
        stop_unit(&c->units[i]);
        free(c->units[i].name);
        free(c->units[i].identifier);
        free(c->units[i].guid);
    }
    for (size_t i = 0; i < c->n_blocks; ++i) {
        free(c->blocks[i].from_vr);
        free(c->blocks[i].to_vr);
        free(c->blocks[i].values);
    }
    for (size_t i = 0; i < c->n_variables; ++i) free(c->variables[i].name);
    free(c->units);
    free(c->blocks);
    free(c->variables);
    free(c->scratch_vr);
    free(c->scratch_index);
    free(c->scratch_value);
    free(c->guid);
    free(c->name);
    free(c);
}

/* ------------------------------------------------------------------------------------------------ */
/* Coupling */

/* Copy every connection: all outputs are read before any input is set (Jacobi). */
static fmi2Status exchange(Container *c)
{
    fmi2Status status = fmi2OK;
    for (size_t i = 0; i < c->n_blocks && status <= fmi2Warning; ++i) {
        Block *b = &c->blocks[i];
        Unit *u = &c->units[b->from];
        status = worse(status, checked(c, u, u->fmi.GetReal(u->component, b->from_vr, b->n, b->values),
                                       "fmi2GetReal of %zu coupling outputs", b->n));
    }
    for (size_t i = 0; i < c->n_blocks && status <= fmi2Warning; ++i) {
        Block *b = &c->blocks[i];
        Unit *u = &c->units[b->to];
        status = worse(status, checked(c, u, u->fmi.SetReal(u->component, b->to_vr, b->n, b->values),
                                       "fmi2SetReal of %zu coupling inputs", b->n));
    }
    return status;
}

/* One internal step: every unit from t over h with the inputs it holds, then the exchange. */
static fmi2Status internal_step(Container *c, double t, double h)
{
    fmi2Status status = fmi2OK;
    for (size_t i = 0; i < c->n_units && status <= fmi2Warning; ++i) {
        Unit *u = &c->units[i];
        /* noSetFMUStatePriorToCurrentPoint: the container never restores a unit's state */
        status = worse(status, checked(c, u, u->fmi.DoStep(u->component, t, h, fmi2True),
                                       "fmi2DoStep(t = %.17g s, h = %.17g s)", t, h));
    }
    return status <= fmi2Warning ? worse(status, exchange(c)) : status;
}

/* ------------------------------------------------------------------------------------------------ */
/* Instances */

static int is_live(const Container *c)
{
    int found = 0;
    pthread_mutex_lock(&instances_lock);
    for (const Container *i = instances; i != NULL && !found; i = i->next) found = i == c;
    pthread_mutex_unlock(&instances_lock);
    return found;
}

/* The container behind `component`, or NULL with *status set when the call is refused: a NULL or foreign
 * pointer (fmi2Error, nobody to log to), or a container a unit of which returned fmi2Fatal. */
static Container *enter(fmi2Component component, const char *call, fmi2Status *status)
{
    Container *c = (Container *)component;
    if (c == NULL || !is_live(c)) {
        *status = fmi2Error;
        return NULL;
    }
    if (c->dead) {
        say(c, fmi2Fatal, "%s: refused: %s, and the container cannot be used any more (fmi2FreeInstance)",
            call, c->failure);
        *status = fmi2Fatal;
        return NULL;
    }
    return c;
}

#define ENTER(component, call)                                                                     \
    fmi2Status refused_;                                                                           \
    Container *c = enter((component), (call), &refused_);                                          \
    if (c == NULL) return refused_

/* A call that moves the units on ends in `status`: after a failure the container steps no more. */
static fmi2Status moved(Container *c, fmi2Status status)
{
    if (status > fmi2Warning) c->failed = 1;
    return status;
}

/* fmi2Error, with the reason, when the container failed before and `call` would move the units on. */
static int refused_after_failure(Container *c, const char *call)
{
    if (!c->failed) return 0;
    refuse(c, "%s: refused: an earlier call failed (%s); call fmi2Reset or fmi2FreeInstance", call,
           c->failure);
    return 1;
}

static const char *phase_name(Phase p)
{
    static const char *names[] = {"instantiated", "in initialization mode", "stepping", "terminated"};
    return names[p];
}

/* Buffers for `n` values forwarded to a unit; 0 if out of memory. */
static int scratch(Container *c, size_t n)
{
    if (n <= c->scratch_size) return 1;
    fmi2ValueReference *vr = realloc(c->scratch_vr, n * sizeof *vr);
    if (vr != NULL) c->scratch_vr = vr;
    size_t *index = realloc(c->scratch_index, n * sizeof *index);
    if (index != NULL) c->scratch_index = index;
    fmi2Real *value = realloc(c->scratch_value, n * sizeof *value);
    if (value != NULL) c->scratch_value = value;
    if (vr == NULL || index == NULL || value == NULL) return 0;
    c->scratch_size = n;
    return 1;
}

/* The variable of value reference `vr`, NULL if there is none. */
static const Variable *variable(const Container *c, fmi2ValueReference vr)
{
    if (vr == 0) {
        static const Variable time_variable = {TIME, 0, 0, "time"};
        return &time_variable;
    }
    return vr < c->n_variables && c->variables[vr].kind != UNUSED ? &c->variables[vr] : NULL;
}

/* ------------------------------------------------------------------------------------------------ */
/* FMI 2.0: creation and destruction */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

/* The container's resources folder and configuration checked, then every unit started. */
static int start(Container *c, fmi2String fmuGUID, fmi2String location, fmi2Boolean logging_on)
{
    char *resources = location != NULL ? malloc(strlen(location) + 1) : NULL;
    if (resources == NULL || !file_uri_to_path(location, resources, strlen(location) + 1)) {
        free(resources);
        say(c, fmi2Error, "fmi2Instantiate: the resource location %s is not a file URI of a local folder",
            location != NULL ? location : "(null)");
        return 0;
    }
    int ok = read_config(c, resources);
    if (ok && (fmuGUID == NULL || strcmp(fmuGUID, c->guid) != 0)) {
        say(c, fmi2Error, "fmi2Instantiate: GUID %s does not match this FMU's %s",
            fmuGUID != NULL ? fmuGUID : "(null)", c->guid);
        ok = 0;
    }
    for (size_t i = 0; ok && i < c->n_units; ++i) ok = start_unit(&c->units[i], resources, logging_on);
    free(resources);
    return ok && apply_starts(c, "fmi2Instantiate") <= fmi2Warning;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    (void)visible;
    if (functions == NULL || functions->logger == NULL) return NULL; /* nobody to tell why */
    Container *c = calloc(1, sizeof *c);
    if (c == NULL) return NULL;
    memcpy(&c->host, functions, sizeof c->host);
    c->name = strdup(instanceName != NULL ? instanceName : "");
    if (c->name == NULL) {
        free(c);
        return NULL;
    }
    int ok = 1;
    if (instanceName == NULL || instanceName[0] == '\0') {
        say(c, fmi2Error, "fmi2Instantiate: the instance name is empty");
        ok = 0;
    } else if (fmuType != fmi2CoSimulation) {
        say(c, fmi2Error, "fmi2Instantiate: this FMU supports Co-Simulation only, not Model Exchange");
        ok = 0;
    }
    if (!ok || !start(c, fmuGUID, fmuResourceLocation, loggingOn)) {
        destroy(c);
        return NULL;
    }
    pthread_mutex_lock(&instances_lock);
    c->next = instances;
    instances = c;
    pthread_mutex_unlock(&instances_lock);
    return c;
}

void fmi2FreeInstance(fmi2Component component)
{
    Container *c = (Container *)component;
    pthread_mutex_lock(&instances_lock);
    Container **link = &instances;
    while (*link != NULL && *link != c) link = &(*link)->next;
    int found = c != NULL && *link != NULL;
    if (found) *link = c->next;
    pthread_mutex_unlock(&instances_lock);
    if (found) destroy(c);
}

/* ------------------------------------------------------------------------------------------------ */
/* FMI 2.0: the experiment, initialization, termination */

fmi2Status fmi2SetDebugLogging(fmi2Component component, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    ENTER(component, "fmi2SetDebugLogging");
    fmi2Status status = fmi2OK;
    for (size_t i = 0; i < c->n_units && status <= fmi2Warning; ++i) {
        Unit *u = &c->units[i];
        fmi2Status s = u->fmi.SetDebugLogging(u->component, loggingOn, nCategories, categories);
        status = worse(status, checked(c, u, s, "fmi2SetDebugLogging"));
    }
    return status;
}

fmi2Status fmi2SetupExperiment(fmi2Component component, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    ENTER(component, "fmi2SetupExperiment");
    if (c->phase != INSTANTIATED)
        return refuse(c, "fmi2SetupExperiment: refused: allowed after fmi2Instantiate only, the container "
                      "is %s", phase_name(c->phase));
    if (refused_after_failure(c, "fmi2SetupExperiment")) return fmi2Error;
    fmi2Status status = fmi2OK;
    for (size_t i = 0; i < c->n_units && status <= fmi2Warning; ++i) {
        Unit *u = &c->units[i];
        status = worse(status, checked(c, u, u->fmi.SetupExperiment(u->component, toleranceDefined, tolerance,
                                                                    startTime, stopTimeDefined, stopTime),
                                       "fmi2SetupExperiment(start %.17g s)", startTime));
    }
    if (status <= fmi2Warning) c->time = startTime;
    return moved(c, status);
}

fmi2Status fmi2EnterInitializationMode(fmi2Component component)
{
    ENTER(component, "fmi2EnterInitializationMode");
    if (c->phase != INSTANTIATED)
        return refuse(c, "fmi2EnterInitializationMode: refused: allowed after fmi2Instantiate only, the "
                      "container is %s", phase_name(c->phase));
    if (refused_after_failure(c, "fmi2EnterInitializationMode")) return fmi2Error;
    fmi2Status status = fmi2OK;
    for (size_t i = 0; i < c->n_units && status <= fmi2Warning; ++i) {
        Unit *u = &c->units[i];
        status = worse(status, checked(c, u, u->fmi.EnterInitializationMode(u->component),
                                       "fmi2EnterInitializationMode"));
    }
    if (status <= fmi2Warning) c->phase = INITIALIZATION;
    return moved(c, status);
}

fmi2Status fmi2ExitInitializationMode(fmi2Component component)
{
    ENTER(component, "fmi2ExitInitializationMode");
    if (c->phase != INITIALIZATION)
        return refuse(c, "fmi2ExitInitializationMode: refused: allowed in initialization mode only, the "
                      "container is %s", phase_name(c->phase));
    if (refused_after_failure(c, "fmi2ExitInitializationMode")) return fmi2Error;
    fmi2Status status = fmi2OK;
    for (size_t i = 0; i < c->n_units && status <= fmi2Warning; ++i) {
        Unit *u = &c->units[i];
        status = worse(status, checked(c, u, u->fmi.ExitInitializationMode(u->component),
                                       "fmi2ExitInitializationMode"));
    }
    /* the initial outputs across, once: each unit's first step starts from the other's initial state */
    if (status <= fmi2Warning) status = worse(status, exchange(c));
    if (status <= fmi2Warning) c->phase = STEPPING;
    return moved(c, status);
}

fmi2Status fmi2Terminate(fmi2Component component)
{
    ENTER(component, "fmi2Terminate");
    if (c->phase != STEPPING)
        return refuse(c, "fmi2Terminate: refused: allowed after initialization only, the container is %s",
                      phase_name(c->phase));
    fmi2Status status = fmi2OK;
    /* every unit is told, even after another's error */
    for (size_t i = 0; i < c->n_units && status != fmi2Fatal; ++i) {
        Unit *u = &c->units[i];
        status = worse(status, checked(c, u, u->fmi.Terminate(u->component), "fmi2Terminate"));
    }
    c->phase = TERMINATED;
    return moved(c, status);
}

fmi2Status fmi2Reset(fmi2Component component)
{
    ENTER(component, "fmi2Reset");
    fmi2Status status = fmi2OK;
    for (size_t i = 0; i < c->n_units && status != fmi2Fatal; ++i) {
        Unit *u = &c->units[i];
        status = worse(status, checked(c, u, u->fmi.Reset(u->component), "fmi2Reset"));
    }
    if (status <= fmi2Warning) status = worse(status, apply_starts(c, "fmi2Reset"));
    c->phase = INSTANTIATED;
    c->time = 0.0;
    c->failed = 0;
    return moved(c, status);
}

/* ------------------------------------------------------------------------------------------------ */
/* FMI 2.0: stepping */

static double magnitude(double x) { return x < 0 ? -x : x; }

static int finite(double x) { return x - x == 0.0; } /* NaN and inf give NaN */

fmi2Status fmi2DoStep(fmi2Component component, fmi2Real t, fmi2Real H,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    ENTER(component, "fmi2DoStep");
    if (c->phase != STEPPING)
        return refuse(c, "fmi2DoStep: refused: allowed after fmi2ExitInitializationMode and before "
                      "fmi2Terminate, the container is %s", phase_name(c->phase));
    if (refused_after_failure(c, "fmi2DoStep")) return fmi2Error;
    if (!(finite(H) && H > 0.0))
        return refuse(c, "fmi2DoStep: refused: the step size %.17g s is not a finite number > 0", H);
    double tolerance = TIME_TOLERANCE * (magnitude(t) > 1.0 ? magnitude(t) : 1.0);
    if (!finite(t) || magnitude(t - c->time) > tolerance)
        return refuse(c, "fmi2DoStep: refused: the communication point t = %.17g s is not the container's "
                      "time %.17g s (tolerance %.1g s): step on from the container's time", t, c->time,
                      tolerance);
    double end = t + H;
    if (!(end > t))
        return refuse(c, "fmi2DoStep: refused: the step size %.17g s does not advance t = %.17g s", H, t);
    /* internal steps of c->step from t, the last one to `end` exactly; a remainder below STEP_SLACK of a
     * step joins the last step instead of being taken as a sliver */
    for (double k = 0.0;; k += 1.0) {
        double tk = t + k * c->step;
        int last = end - tk <= c->step * (1.0 + STEP_SLACK);
        fmi2Status status = internal_step(c, tk, last ? end - tk : c->step);
        if (status > fmi2Warning) return moved(c, status);
        if (last) break;
    }
    c->time = end;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component component)
{
    ENTER(component, "fmi2CancelStep");
    return refuse(c, "fmi2CancelStep: refused: the container steps synchronously: no step to cancel");
}

/* ------------------------------------------------------------------------------------------------ */
/* FMI 2.0: variables */

/* Check that every value reference names a variable; 0 (the refusal logged) if one does not. */
static int known(Container *c, const char *call, const fmi2ValueReference vr[], size_t nvr, const void *value)
{
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        refuse(c, "%s: refused: NULL value reference or value array for %zu values", call, nvr);
        return 0;
    }
    for (size_t i = 0; i < nvr; ++i) {
        if (variable(c, vr[i]) == NULL) {
            refuse(c, "%s: refused: %u is not a value reference of this FMU; nothing was done", call, vr[i]);
            return 0;
        }
    }
    return 1;
}

/* Gather the value references of unit `u` among vr[] into the scratch buffers; returns their count. */
static size_t gather(Container *c, size_t u, const fmi2ValueReference vr[], size_t nvr)
{
    size_t m = 0;
    for (size_t i = 0; i < nvr; ++i) {
        const Variable *v = variable(c, vr[i]);
        if (v->kind != TIME && v->unit == u) {
            c->scratch_vr[m] = v->unit_vr;
            c->scratch_index[m++] = i;
        }
    }
    return m;
}

fmi2Status fmi2GetReal(fmi2Component component, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    ENTER(component, "fmi2GetReal");
    if (!known(c, "fmi2GetReal", vr, nvr, value)) return fmi2Error;
    if (!scratch(c, nvr)) return refuse(c, "fmi2GetReal: out of memory");
    fmi2Status status = fmi2OK;
    for (size_t u = 0; u < c->n_units && status <= fmi2Warning; ++u) { /* one call per unit */
        size_t m = gather(c, u, vr, nvr);
        if (m == 0) continue;
        Unit *unit = &c->units[u];
        fmi2Status s = unit->fmi.GetReal(unit->component, c->scratch_vr, m, c->scratch_value);
        status = worse(status, checked(c, unit, s, "fmi2GetReal of %zu values", m));
        for (size_t j = 0; j < m; ++j) value[c->scratch_index[j]] = c->scratch_value[j];
    }
    for (size_t i = 0; i < nvr; ++i)
        if (vr[i] == 0) value[i] = c->time;
    return status;
}

fmi2Status fmi2SetReal(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[])
{
    ENTER(component, "fmi2SetReal");
    if (!known(c, "fmi2SetReal", vr, nvr, value)) return fmi2Error;
    for (size_t i = 0; i < nvr; ++i) {
        const Variable *v = variable(c, vr[i]);
        if (v->kind != PARAMETER)
            return refuse(c, "fmi2SetReal: refused: %s is %s, only parameters can be set; nothing was set",
                          v->name, v->kind == TIME ? "the independent variable" : "an output");
        if (c->phase != INSTANTIATED && c->phase != INITIALIZATION)
            return refuse(c, "fmi2SetReal: refused: the parameter %s can be set before "
                          "fmi2ExitInitializationMode only, the container is %s; nothing was set", v->name,
                          phase_name(c->phase));
    }
    if (!scratch(c, nvr)) return refuse(c, "fmi2SetReal: out of memory");
    fmi2Status status = fmi2OK;
    for (size_t u = 0; u < c->n_units && status <= fmi2Warning; ++u) {
        size_t m = gather(c, u, vr, nvr);
        if (m == 0) continue;
        for (size_t j = 0; j < m; ++j) c->scratch_value[j] = value[c->scratch_index[j]];
        Unit *unit = &c->units[u];
        fmi2Status s = unit->fmi.SetReal(unit->component, c->scratch_vr, m, c->scratch_value);
        status = worse(status, checked(c, unit, s, "fmi2SetReal of %zu parameters", m));
    }
    return status;
}

/* The container has Real variables only: a call on other types is refused unless it names none. */
static fmi2Status not_real(fmi2Component component, const char *call, size_t nvr)
{
    ENTER(component, call);
    if (nvr == 0) return fmi2OK;
    return refuse(c, "%s: refused: this FMU has Real variables only; nothing was done", call);
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    (void)vr, (void)value;
    return not_real(c, "fmi2GetInteger", nvr);
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    (void)vr, (void)value;
    return not_real(c, "fmi2GetBoolean", nvr);
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    (void)vr, (void)value;
    return not_real(c, "fmi2GetString", nvr);
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[])
{
    (void)vr, (void)value;
    return not_real(c, "fmi2SetInteger", nvr);
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[])
{
    (void)vr, (void)value;
    return not_real(c, "fmi2SetBoolean", nvr);
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[])
{
    (void)vr, (void)value;
    return not_real(c, "fmi2SetString", nvr);
}

/* ------------------------------------------------------------------------------------------------ */
/* FMI 2.0: what the model description says the container cannot do */

static fmi2Status unsupported(fmi2Component component, const char *call, const char *why)
{
    ENTER(component, call);
    return refuse(c, "%s: refused: %s", call, why);
}

#define NO_STATE "the container cannot save or restore its state (canGetAndSetFMUstate is false)"

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    (void)state;
    return unsupported(c, "fmi2GetFMUstate", NO_STATE);
}
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state)
{
    (void)state;
    return unsupported(c, "fmi2SetFMUstate", NO_STATE);
}
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    (void)state;
    return unsupported(c, "fmi2FreeFMUstate", NO_STATE);
}
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size)
{
    (void)state, (void)size;
    return unsupported(c, "fmi2SerializedFMUstateSize", NO_STATE);
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size)
{
    (void)state, (void)bytes, (void)size;
    return unsupported(c, "fmi2SerializeFMUstate", NO_STATE);
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate *state)
{
    (void)bytes, (void)size, (void)state;
    return unsupported(c, "fmi2DeSerializeFMUstate", NO_STATE);
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference unknown[], size_t n_unknown,
                                        const fmi2ValueReference known_vr[], size_t n_known,
                                        const fmi2Real dv_known[], fmi2Real dv_unknown[])
{
    (void)unknown, (void)n_unknown, (void)known_vr, (void)n_known, (void)dv_known, (void)dv_unknown;
    return unsupported(c, "fmi2GetDirectionalDerivative", "the container has no directional derivatives");
}
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    (void)vr, (void)nvr, (void)order, (void)value;
    return unsupported(c, "fmi2SetRealInputDerivatives", "the container has no inputs to interpolate");
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    (void)vr, (void)nvr, (void)order, (void)value;
    return unsupported(c, "fmi2GetRealOutputDerivatives", "the container provides no output derivatives");
}

#define NO_STATUS "the container steps synchronously and has no status to query but fmi2LastSuccessfulTime"

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    (void)s, (void)value;
    return unsupported(c, "fmi2GetStatus", NO_STATUS);
}
fmi2Status fmi2GetRealStatus(fmi2Component component, const fmi2StatusKind s, fmi2Real *value)
{
    ENTER(component, "fmi2GetRealStatus");
    if (s != fmi2LastSuccessfulTime || value == NULL)
        return refuse(c, "fmi2GetRealStatus: refused: %s", NO_STATUS);
    *value = c->time;
    return fmi2OK;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    (void)s, (void)value;
    return unsupported(c, "fmi2GetIntegerStatus", NO_STATUS);
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    (void)s, (void)value;
    return unsupported(c, "fmi2GetBooleanStatus", NO_STATUS);
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    (void)s, (void)value;
    return unsupported(c, "fmi2GetStringStatus", NO_STATUS);
}
