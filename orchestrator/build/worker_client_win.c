/* The worker's life on Windows: included by worker_client.c in place of its Linux section, with the
 * same functions (open_channel, find_worker, worker_alive, ended, release, binary_folder).
 *
 * Every instance starts a worker of its own (no sharing between units: simpler, and a unit's worker costs
 * one process more in a coupled run). fmi2Instantiate creates, all inheritable: the channel (a
 * pagefile-backed section), the control page (a small one), two auto-reset events (the worker sleeps on
 * one, this client on the other), a SYNCHRONIZE handle of the host process (the worker's lifeline: a thread
 * of the worker waits on it and ends the worker when the host ends, however) and a temporary file that is
 * deleted when its last handle closes (the worker's stdout and stderr). It starts
 *     <folder of this binary>\SHIM_WORKER "<pythonfmu binary>" "<runtime>" SECTION CONTROL WAKE_WORKER
 *                                         WAKE_CLIENT HOST          (handle values in hexadecimal)
 * suspended, inheriting those handles only (PROC_THREAD_ATTRIBUTE_HANDLE_LIST), with an environment of
 * SystemRoot, the host's WINGSIM_* variables and one BLAS thread, puts it into a job object that kills it
 * when the job's last handle closes (this process's, however it ends), and lets it run. A worker ends
 *   - after the fmi2FreeInstance of its instance (killed if it has not ended within WORKER_EXIT_WAIT_MS);
 *   - when the host process ends: its job closes, and its lifeline thread sees the host's handle signalled;
 * and this client sees it end, in any way, through its process handle (asked while it waits for an answer).
 * Then the call returns fmi2Fatal with the reason logged (the exit code and the end of its output). */

/* The folder of this binary (with a trailing '\'), UTF-8. */
static int binary_folder(char *path, size_t size)
{
    HMODULE self;
    wchar_t wide[MAX_PATH * 4];
    if (!GetModuleHandleExW(GET_MODULE_HANDLE_EX_FLAG_FROM_ADDRESS | GET_MODULE_HANDLE_EX_FLAG_UNCHANGED_REFCOUNT,
                            (LPCWSTR)(void *)&binary_folder, &self))
        return 0;
    DWORD n = GetModuleFileNameW(self, wide, sizeof wide / sizeof *wide);
    if (n == 0 || n >= sizeof wide / sizeof *wide) return 0;
    wchar_t *slash = wcsrchr(wide, L'\\');
    if (slash == NULL) return 0;
    slash[1] = L'\0';
    return utf8_string(wide, path, size);
}

static int worker_alive(void *arg)
{
    Worker *w = (Worker *)arg;
    return WaitForSingleObject(w->process, 0) == WAIT_TIMEOUT;
}

/* The worker ended during `function`: log why, with the end of its output. */
static fmi2Status ended(Worker *w, const char *function)
{
    if (w->gone) return fmi2Fatal;
    w->gone = 1;
    DWORD code = 0;
    WaitForSingleObject(w->process, 1000);
    if (!GetExitCodeProcess(w->process, &code)) code = (DWORD)-1;
    char tail[OUTPUT_TAIL + 1] = "";
    LARGE_INTEGER size;
    DWORD got = 0;
    if (GetFileSizeEx(w->output, &size)) {
        OVERLAPPED at = {0};
        LONGLONG from = size.QuadPart > OUTPUT_TAIL ? size.QuadPart - OUTPUT_TAIL : 0;
        at.Offset = (DWORD)from;
        at.OffsetHigh = (DWORD)(from >> 32);
        if (!ReadFile(w->output, tail, (DWORD)(size.QuadPart - from), &got, &at)) got = 0;
    }
    tail[got] = '\0';
    tell(w, fmi2Fatal, "%s: the unit's worker process (pid %lu) ended with exit code %lu (0x%08lx); the instance "
         "cannot be used any more%s%s", function, (unsigned long)w->pid, (unsigned long)code, (unsigned long)code,
         tail[0] != '\0' ? ". Its last output: " : "", tail);
    return fmi2Fatal;
}

static SECURITY_ATTRIBUTES inheritable = {sizeof(SECURITY_ATTRIBUTES), NULL, TRUE};

/* This instance's channel: a section reserving CHANNEL_MAX_SIZE, its first pages committed. */
static int open_channel(Worker *w)
{
    w->ch.section = CreateFileMappingW(INVALID_HANDLE_VALUE, &inheritable, PAGE_READWRITE | SEC_RESERVE,
                                       (DWORD)(CHANNEL_MAX_SIZE >> 32), (DWORD)CHANNEL_MAX_SIZE, NULL);
    if (w->ch.section == NULL || !channel_map(&w->ch, CHANNEL_INITIAL_SIZE)) {
        tell(w, fmi2Error, "fmi2Instantiate: cannot create the channel to the worker: Windows error %lu", GetLastError());
        return 0;
    }
    return 1;
}

/* Append the string `item` and its NUL to the block being built; 0 when out of memory. */
static int append_wide(wchar_t **block, size_t *k, size_t *cap, const wchar_t *item)
{
    size_t n = wcslen(item) + 1;
    if (*k + n > *cap) {
        size_t grown_cap = 2 * (*cap + n);
        wchar_t *grown = realloc(*block, grown_cap * sizeof *grown);
        if (grown == NULL) return 0;
        *block = grown;
        *cap = grown_cap;
    }
    memcpy(*block + *k, item, n * sizeof *item);
    *k += n;
    return 1;
}

/* The worker's environment block: SystemRoot (Windows's own DLLs need it), the host's WINGSIM_* variables,
 * one BLAS thread; nothing else of the host's reaches the unit. NULL when out of memory. */
static wchar_t *worker_environment(void)
{
    wchar_t *block = NULL;
    size_t k = 0, cap = 0;
    int ok = 1;
    wchar_t *host = GetEnvironmentStringsW();
    for (const wchar_t *e = host; ok && e != NULL && *e != L'\0'; e += wcslen(e) + 1)
        if (_wcsnicmp(e, L"SystemRoot=", 11) == 0 || _wcsnicmp(e, L"WINGSIM_", 8) == 0)
            ok = append_wide(&block, &k, &cap, e);
    if (host != NULL) FreeEnvironmentStringsW(host);
    ok = ok && append_wide(&block, &k, &cap, L"OPENBLAS_NUM_THREADS=1")
         && append_wide(&block, &k, &cap, L"OMP_NUM_THREADS=1") && append_wide(&block, &k, &cap, L"");
    if (!ok) {
        free(block);
        return NULL;
    }
    return block;
}

/* The worker's output: a temporary file, gone when its last handle closes. */
static HANDLE output_file(void)
{
    wchar_t folder[MAX_PATH + 1], name[MAX_PATH + 1];
    if (GetTempPathW(MAX_PATH + 1, folder) == 0 || GetTempFileNameW(folder, L"wsw", 0, name) == 0)
        return INVALID_HANDLE_VALUE;
    return CreateFileW(name, GENERIC_READ | GENERIC_WRITE, FILE_SHARE_READ | FILE_SHARE_WRITE | FILE_SHARE_DELETE,
                       &inheritable, CREATE_ALWAYS, FILE_ATTRIBUTE_TEMPORARY | FILE_FLAG_DELETE_ON_CLOSE, NULL);
}

/* Start `program` with `command` and the environment `environment`, inheriting the handles `inherit` only,
 * with `output` as stdout and stderr, suspended; the process information, or 0 with the Windows error. */
static int start_process(const wchar_t *program, wchar_t *command, wchar_t *environment, HANDLE *inherit,
                         size_t n_inherit, HANDLE output, PROCESS_INFORMATION *process, DWORD *error)
{
    SIZE_T size = 0;
    InitializeProcThreadAttributeList(NULL, 1, 0, &size);
    LPPROC_THREAD_ATTRIBUTE_LIST list = HeapAlloc(GetProcessHeap(), 0, size);
    BOOL ok = list != NULL && InitializeProcThreadAttributeList(list, 1, 0, &size)
              && UpdateProcThreadAttribute(list, 0, PROC_THREAD_ATTRIBUTE_HANDLE_LIST, inherit,
                                           n_inherit * sizeof *inherit, NULL, NULL);
    if (ok) {
        STARTUPINFOEXW info;
        memset(&info, 0, sizeof info);
        info.StartupInfo.cb = sizeof info;
        info.StartupInfo.dwFlags = STARTF_USESTDHANDLES;
        info.StartupInfo.hStdOutput = info.StartupInfo.hStdError = output;
        info.lpAttributeList = list;
        ok = CreateProcessW(program, command, NULL, NULL, TRUE,
                            EXTENDED_STARTUPINFO_PRESENT | CREATE_SUSPENDED | CREATE_NO_WINDOW
                                | CREATE_UNICODE_ENVIRONMENT,
                            environment, NULL, &info.StartupInfo, process);
    }
    *error = GetLastError();
    if (list != NULL) {
        DeleteProcThreadAttributeList(list);
        HeapFree(GetProcessHeap(), 0, list);
    }
    return ok;
}

/* Start this instance's worker (module comment); 0, the reason logged, on failure. */
static int find_worker(Worker *w, const char *folder)
{
    char worker[4096], inner[4096], runtime[4096];
    snprintf(worker, sizeof worker, "%s%s", folder, SHIM_WORKER);
    snprintf(inner, sizeof inner, "%s%s", folder, SHIM_INNER);
    snprintf(runtime, sizeof runtime, "%sruntime", folder);
    if (!file_readable(worker) || !file_readable(runtime)) {
        tell(w, fmi2Error, "fmi2Instantiate: the FMU's worker or runtime is missing: %s, %s (an incomplete "
                           "FMU: rebuild it with wingsim build --standalone --win64)", worker, runtime);
        return 0;
    }
    HANDLE host = NULL;
    w->control_section = CreateFileMappingW(INVALID_HANDLE_VALUE, &inheritable, PAGE_READWRITE, 0,
                                            WORKER_CONTROL_SIZE, NULL);
    w->control = w->control_section != NULL ? MapViewOfFile(w->control_section, FILE_MAP_READ | FILE_MAP_WRITE, 0,
                                                            0, WORKER_CONTROL_SIZE)
                                            : NULL;
    w->wake_worker = CreateEventW(&inheritable, FALSE, FALSE, NULL);
    w->wake_client = CreateEventW(&inheritable, FALSE, FALSE, NULL);
    w->output = output_file();
    if (w->control == NULL || w->wake_worker == NULL || w->wake_client == NULL || w->output == INVALID_HANDLE_VALUE
        || !DuplicateHandle(GetCurrentProcess(), GetCurrentProcess(), GetCurrentProcess(), &host, SYNCHRONIZE, TRUE, 0)) {
        tell(w, fmi2Error, "fmi2Instantiate: cannot create the worker's control page: Windows error %lu",
             GetLastError());
        return 0;
    }
    w->control->magic = CHANNEL_MAGIC;
    w->control->version = CHANNEL_VERSION;
    atomic_store(&w->control->exit_status, -1);

    wchar_t *program = wide_string(worker), *inner_w = wide_string(inner), *runtime_w = wide_string(runtime);
    wchar_t *environment = worker_environment();
    size_t size = (program && inner_w && runtime_w) ? wcslen(program) + wcslen(inner_w) + wcslen(runtime_w) + 200 : 0;
    wchar_t *command = size > 0 ? malloc(size * sizeof *command) : NULL;
    PROCESS_INFORMATION process = {0};
    DWORD error = ERROR_NOT_ENOUGH_MEMORY;
    int started = 0;
    if (command != NULL && environment != NULL) {
        _snwprintf(command, size, L"\"%ls\" \"%ls\" \"%ls\" %llx %llx %llx %llx %llx", program, inner_w, runtime_w,
                   (unsigned long long)(uintptr_t)w->ch.section, (unsigned long long)(uintptr_t)w->control_section,
                   (unsigned long long)(uintptr_t)w->wake_worker, (unsigned long long)(uintptr_t)w->wake_client,
                   (unsigned long long)(uintptr_t)host);
        HANDLE inherit[] = {w->ch.section, w->control_section, w->wake_worker, w->wake_client, host, w->output};
        started = start_process(program, command, environment, inherit, sizeof inherit / sizeof *inherit, w->output,
                                &process, &error);
    }
    free(program);
    free(inner_w);
    free(runtime_w);
    free(environment);
    free(command);
    CloseHandle(host);                   /* the worker's now: only it waits on the host */
    if (!started) {
        tell(w, fmi2Error, "fmi2Instantiate: cannot start the worker %s: Windows error %lu", worker, error);
        return 0;
    }
    /* The job ends the worker with this process even where the lifeline thread could not run. A host that
     * is itself in a job that forbids nesting cannot assign it: the lifeline still ends the worker. */
    JOBOBJECT_EXTENDED_LIMIT_INFORMATION limits;
    memset(&limits, 0, sizeof limits);
    limits.BasicLimitInformation.LimitFlags = JOB_OBJECT_LIMIT_KILL_ON_JOB_CLOSE;
    w->job = CreateJobObjectW(NULL, NULL);
    if (w->job != NULL
        && !(SetInformationJobObject(w->job, JobObjectExtendedLimitInformation, &limits, sizeof limits)
             && AssignProcessToJobObject(w->job, process.hProcess))) {
        CloseHandle(w->job);
        w->job = NULL;
    }
    ResumeThread(process.hThread);
    CloseHandle(process.hThread);
    w->process = process.hProcess;
    w->pid = process.dwProcessId;
    return 1;
}

static void release(Worker *w, int reaping)
{
    if (w->process != NULL) {
        /* after its last fmi2FreeInstance a worker ends by itself; one that does not is ended here */
        if (WaitForSingleObject(w->process, reaping ? WORKER_EXIT_WAIT_MS : 0) != WAIT_OBJECT_0)
            TerminateProcess(w->process, 1);
        CloseHandle(w->process);
    }
    channel_close(&w->ch);
    if (w->control != NULL) UnmapViewOfFile(w->control);
    HANDLE handles[] = {w->control_section, w->wake_worker, w->wake_client, w->job};
    for (size_t i = 0; i < sizeof handles / sizeof *handles; ++i)
        if (handles[i] != NULL) CloseHandle(handles[i]);
    if (w->output != NULL && w->output != INVALID_HANDLE_VALUE) CloseHandle(w->output);
    free_worker(w);
}
