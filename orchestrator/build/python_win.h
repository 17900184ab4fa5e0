/* The Python C API functions a worker calls, on Windows: looked up in the runtime's python3X.dll
 * (LoadLibrary, GetProcAddress) instead of linked, because the DLL is in runtime\, not beside the worker
 * where the loader would look for a linked one. Each function keeps its name in the worker's code: the name
 * is defined below as a pointer of the function's own type (__typeof__ of its declaration in Python.h).
 *
 * Python.h here is CPython's Include/ with the Windows PC/pyconfig.h of the runtime's minor version
 * (orchestrator/build/win64.py fetches them), compiled with -DMS_WIN64: that pyconfig.h defines it for
 * Microsoft's compiler only, and without it the sizes it declares are those of 32-bit Windows. Included by
 * fmi_worker.c after Python.h. */
#ifndef WINGSIM_PYTHON_WIN_H
#define WINGSIM_PYTHON_WIN_H

#include <windows.h>

_Static_assert(SIZEOF_VOID_P == sizeof(void *) && SIZEOF_SIZE_T == sizeof(size_t) && SIZEOF_LONG == sizeof(long)
               && SIZEOF_WCHAR_T == sizeof(wchar_t), "pyconfig.h does not describe this target: compile with -DMS_WIN64");

#define PYTHON_DLL "python" NUMBER_TEXT(PY_MAJOR_VERSION) NUMBER_TEXT(PY_MINOR_VERSION) ".dll"

#define PYTHON_FUNCTIONS(X)                                                                                  \
    X(PyPreConfig_InitIsolatedConfig) X(Py_PreInitialize) X(PyConfig_InitIsolatedConfig)                     \
    X(PyConfig_SetBytesString) X(PyStatus_Exception) X(PyStatus_NoMemory) X(Py_DecodeLocale) X(PyMem_RawFree) \
    X(PyWideStringList_Append) X(Py_InitializeFromConfig) X(PyConfig_Clear) X(PyEval_SaveThread)
#define PYTHON_POINTER(name) static __typeof__(&name) python_##name;
PYTHON_FUNCTIONS(PYTHON_POINTER)
#undef PYTHON_POINTER

/* Whether the headers describe the DLL's structures: its own initialisers fill ours, each followed by guard
 * bytes, up to their end and no further, with the values of an isolated configuration at fields spread over
 * them. Headers of another minor version would hand every call wrong offsets. */
static int layout_matches(void)
{
    struct {
        PyPreConfig pre;
        unsigned char guard[256];
    } pre;
    struct {
        PyConfig config;
        unsigned char guard[256];
    } config;
    memset(&pre, 0xAB, sizeof pre);
    memset(&config, 0xAB, sizeof config);
    python_PyPreConfig_InitIsolatedConfig(&pre.pre);
    python_PyConfig_InitIsolatedConfig(&config.config);
    for (size_t i = 0; i < sizeof pre.guard; ++i)
        if (pre.guard[i] != 0xAB || config.guard[i] != 0xAB) return 0;
    return pre.pre.isolated == 1 && pre.pre.use_environment == 0 && config.config.isolated == 1
           && config.config.use_environment == 0 && config.config._install_importlib == 1
           && config.config._init_main == 1 && config.config._is_python_build == 0;
}

/* Load RUNTIME\python3X.dll and resolve the functions; 0 and startup_error on failure. */
static int load_python(const char *runtime)
{
    char path[PATH_SIZE];
    wchar_t *folder = wide_string(runtime);
    /* The runtime's folder is searched for every DLL loaded from now on: pythonfmu's binary imports
     * MSVCP140.dll and VCRUNTIME140_1.dll, which the runtime carries (a Windows without Microsoft's Visual
     * C++ redistributable has neither). */
    BOOL searched = folder != NULL && SetDllDirectoryW(folder);
    free(folder);
    if (!searched) {
        snprintf(startup_error, sizeof startup_error, "cannot search %s for DLLs: Windows error %lu", runtime,
                 GetLastError());
        return 0;
    }
    snprintf(path, sizeof path, "%s\\python3.dll", runtime);
    char error[MESSAGE_SIZE];
    void *dll = library_open(path, error, sizeof error);   /* pythonfmu's binary imports it: loaded first */
    snprintf(path, sizeof path, "%s\\" PYTHON_DLL, runtime);
    if (dll != NULL) dll = library_open(path, error, sizeof error);
    if (dll == NULL) {
        snprintf(startup_error, sizeof startup_error, "starting the FMU's Python failed: %s", error);
        return 0;
    }
#define PYTHON_RESOLVE(name)                                                                                 \
    if ((python_##name = (__typeof__(&name))library_symbol(dll, #name)) == NULL) {                          \
        snprintf(startup_error, sizeof startup_error, "%s does not provide %s", path, #name);                 \
        return 0;                                                                                           \
    }
    PYTHON_FUNCTIONS(PYTHON_RESOLVE)
#undef PYTHON_RESOLVE
    if (!layout_matches()) {
        snprintf(startup_error, sizeof startup_error, "the worker was compiled with Python headers that do not "
                 "describe %s (PyConfig's layout differs)", path);
        return 0;
    }
    return 1;
}

#define PyPreConfig_InitIsolatedConfig python_PyPreConfig_InitIsolatedConfig
#define Py_PreInitialize python_Py_PreInitialize
#define PyConfig_InitIsolatedConfig python_PyConfig_InitIsolatedConfig
#define PyConfig_SetBytesString python_PyConfig_SetBytesString
#define PyStatus_Exception python_PyStatus_Exception
#define PyStatus_NoMemory python_PyStatus_NoMemory
#define Py_DecodeLocale python_Py_DecodeLocale
#define PyMem_RawFree python_PyMem_RawFree
#define PyWideStringList_Append python_PyWideStringList_Append
#define Py_InitializeFromConfig python_Py_InitializeFromConfig
#define PyConfig_Clear python_PyConfig_Clear
#define PyEval_SaveThread python_PyEval_SaveThread

#endif
