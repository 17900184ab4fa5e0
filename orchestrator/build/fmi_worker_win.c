/* A worker's start on Windows: included by fmi_worker.c in place of its Linux section. Started by its
 * instance's client (worker_client_win.c) as
 *     <id>_worker.exe PYTHONFMU_BINARY RUNTIME SECTION CONTROL WAKE_WORKER WAKE_CLIENT HOST
 * the last five being handles it inherited, in hexadecimal: the channel's section, the control page's, the
 * event it sleeps on, the event its client sleeps on, and the host process (SYNCHRONIZE). It serves that one
 * instance in slot 0 with the loop every worker runs (serve_forever). A thread waits on the host's handle
 * and ends the worker at once when the host ends, however (the lifeline; the client's job object ends it
 * too). */

static DWORD WINAPI lifeline(LPVOID host)
{
    WaitForSingleObject((HANDLE)host, INFINITE);
    end_worker(0);                       /* the host is gone: nothing to finish, nobody to answer */
    return 0;
}

static HANDLE handle_argument(const wchar_t *text) { return (HANDLE)(uintptr_t)wcstoull(text, NULL, 16); }

int wmain(int argc, wchar_t **argv)
{
    if (argc != 8) {
        fprintf(stderr, "usage: %ls PYTHONFMU_BINARY RUNTIME SECTION CONTROL WAKE_WORKER WAKE_CLIENT HOST "
                        "(started by a wingsim FMU)\n", argv[0]);
        return 2;
    }
    if (CreateThread(NULL, 0, lifeline, handle_argument(argv[7]), 0, NULL) == NULL) return 3;
    wchar_t self[PATH_SIZE];
    char program[PATH_SIZE], inner[PATH_SIZE], runtime[PATH_SIZE];
    DWORD n = GetModuleFileNameW(NULL, self, PATH_SIZE);
    if (n == 0 || n >= PATH_SIZE || !utf8_string(self, program, sizeof program)
        || !utf8_string(argv[1], inner, sizeof inner) || !utf8_string(argv[2], runtime, sizeof runtime))
        return 2;
    control = MapViewOfFile(handle_argument(argv[4]), FILE_MAP_READ | FILE_MAP_WRITE, 0, 0, WORKER_CONTROL_SIZE);
    if (control == NULL || control->magic != CHANNEL_MAGIC || control->version != CHANNEL_VERSION) return 4;
    doorbell_event = handle_argument(argv[5]);
    Slot *slot = &slots[0];
    slot->channel.section = handle_argument(argv[3]);
    if (!channel_map(&slot->channel, CHANNEL_INITIAL_SIZE) || !channel_sync(&slot->channel)
        || slot->channel.head->magic != CHANNEL_MAGIC || slot->channel.head->version != CHANNEL_VERSION)
        return 4;
    slot->wake_client = handle_argument(argv[6]);
    slot->socket = -1;
    slot->answered = atomic_load(&slot->channel.head->response);
    atomic_store(&slot->used, 1);
    if (start_python(program, runtime)) load_pythonfmu(inner);
    serve_forever();
    return 0;
}
