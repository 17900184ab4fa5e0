/* Resource locations: the local path of a file URI, as FMI 2.0 hosts spell it (file:///p, file:/p,
 * file://localhost/p, percent escapes): used by fmi_shim.c and container.c. */
#ifndef WINGSIM_FMI2_URI_H
#define WINGSIM_FMI2_URI_H

#include <stddef.h>
#include <string.h>

static int uri_hex_value(char c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

/* The absolute path of the file URI `uri` into `path` (`size` bytes), percent escapes decoded and
 * without a trailing '/'; 0 if `uri` is not a file URI of a local path (or "%00", or too long). On Windows
 * the path of file:///C:/dir is C:/dir (forward slashes, which Windows accepts). */
static int file_uri_to_path(const char *uri, char *path, size_t size)
{
    const char *p;
    if (strncmp(uri, "file://localhost/", 17) == 0) p = uri + 16;
    else if (strncmp(uri, "file:///", 8) == 0) p = uri + 7;
    else if (strncmp(uri, "file:/", 6) == 0 && uri[6] != '/') p = uri + 5;
    else return 0;
    size_t k = 0;
    for (; *p != '\0'; ++p) {
        char c = *p;
        if (c == '%' && uri_hex_value(p[1]) >= 0 && uri_hex_value(p[2]) >= 0) {
            c = (char)(uri_hex_value(p[1]) * 16 + uri_hex_value(p[2]));
            p += 2;
        }
        if (c == '\0' || k + 1 >= size) return 0;
        path[k++] = c;
    }
    while (k > 1 && path[k - 1] == '/') --k;
    path[k] = '\0';
#ifdef _WIN32
    if (k >= 3 && path[0] == '/' && path[2] == ':') memmove(path, path + 1, k);   /* "/C:/dir" -> "C:/dir" */
#endif
    return 1;
}

#endif
