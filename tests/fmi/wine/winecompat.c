/* winecompat.dll: for the tests under Wine only, never part of an FMU. Wine 8.0's ucrtbase.dll exports the C99
 * complex functions (cexp, crealf, cabs, ... and _Cbuild/_Cmulcc) only as unimplemented stubs: calling one aborts
 * the process ("Unimplemented function ucrtbase.dll.crealf called"). numpy's _multiarray_umath calls crealf while
 * it is imported. Loaded into a process under Wine before numpy, this DLL overwrites each such stub's code in the
 * loaded ucrtbase with a jump to an implementation here (mingw-w64's C99 complex functions), following the MSVC
 * ABI of the UCRT: _Dcomplex/_Lcomplex are struct {double _Val[2]} (MSVC's long double is double), _Fcomplex is
 * struct {float _Val[2]}; GCC's ms_abi passes and returns these structs exactly as MSVC does. Outside Wine, or
 * for functions that are not stubs, it changes nothing. Windows itself implements these functions.
 * Exported: int winecompat_installed(void): how many stubs were replaced (-1: not under Wine). */
#include <windows.h>
#include <complex.h>
#include <math.h>
#include <string.h>

typedef struct { double v[2]; } Dc;   /* _Dcomplex and _Lcomplex */
typedef struct { float v[2]; } Fc;    /* _Fcomplex */

static inline double _Complex D(Dc z) { return __builtin_complex(z.v[0], z.v[1]); }
static inline float _Complex F(Fc z) { return __builtin_complex(z.v[0], z.v[1]); }
static inline Dc DD(double _Complex z) { Dc r = {{creal(z), cimag(z)}}; return r; }
static inline Fc FF(float _Complex z) { Fc r = {{crealf(z), cimagf(z)}}; return r; }

/* complex -> complex */
#define UNARY(name)                                                   \
    static Dc w_##name(Dc z) { return DD(name(D(z))); }                \
    static Fc w_##name##f(Fc z) { return FF(name##f(F(z))); }          \
    static Dc w_##name##l(Dc z) { return DD(name(D(z))); }
UNARY(cacos) UNARY(cacosh) UNARY(casin) UNARY(casinh) UNARY(catan) UNARY(catanh) UNARY(ccos)
UNARY(ccosh) UNARY(cexp) UNARY(clog) UNARY(conj) UNARY(cproj) UNARY(csin) UNARY(csinh) UNARY(csqrt)
UNARY(ctan) UNARY(ctanh)
/* complex -> real */
#define TOREAL(name, expr)                                                            \
    static double w_##name(Dc z) { double _Complex x = D(z); return (expr); }          \
    static float w_##name##f(Fc z) { float _Complex x = F(z); return (float)(expr); }  \
    static double w_##name##l(Dc z) { double _Complex x = D(z); return (expr); }
TOREAL(cabs, cabs(x)) TOREAL(carg, carg(x)) TOREAL(cimag, cimag(x)) TOREAL(creal, creal(x))
TOREAL(norm, creal(x) * creal(x) + cimag(x) * cimag(x))
static Dc w_clog10(Dc z) { return DD(clog(D(z)) / M_LN10); }
static Fc w_clog10f(Fc z) { return FF(clogf(F(z)) / (float)M_LN10); }
static Dc w_clog10l(Dc z) { return DD(clog(D(z)) / M_LN10); }
static Dc w_cpow(Dc x, Dc y) { return DD(cpow(D(x), D(y))); }
static Fc w_cpowf(Fc x, Fc y) { return FF(cpowf(F(x), F(y))); }
static Dc w_cpowl(Dc x, Dc y) { return DD(cpow(D(x), D(y))); }
static Dc w__Cbuild(double re, double im) { Dc r = {{re, im}}; return r; }
static Fc w__FCbuild(float re, float im) { Fc r = {{re, im}}; return r; }
static Dc w__LCbuild(double re, double im) { Dc r = {{re, im}}; return r; }
static Dc w__Cmulcc(Dc x, Dc y) { return DD(D(x) * D(y)); }
static Dc w__Cmulcr(Dc x, double y) { Dc r = {{x.v[0] * y, x.v[1] * y}}; return r; }
static Fc w__FCmulcc(Fc x, Fc y) { return FF(F(x) * F(y)); }
static Fc w__FCmulcr(Fc x, float y) { Fc r = {{x.v[0] * y, x.v[1] * y}}; return r; }
static Dc w__LCmulcc(Dc x, Dc y) { return DD(D(x) * D(y)); }
static Dc w__LCmulcr(Dc x, double y) { Dc r = {{x.v[0] * y, x.v[1] * y}}; return r; }

#define E3(n) {#n, (void *)w_##n}, {#n "f", (void *)w_##n##f}, {#n "l", (void *)w_##n##l},
static const struct { const char *name; void *impl; } table[] = {
    E3(cacos) E3(cacosh) E3(casin) E3(casinh) E3(catan) E3(catanh) E3(ccos) E3(ccosh) E3(cexp) E3(clog)
    E3(conj) E3(cproj) E3(csin) E3(csinh) E3(csqrt) E3(ctan) E3(ctanh) E3(cabs) E3(carg) E3(cimag)
    E3(creal) E3(norm) E3(clog10) E3(cpow)
    {"_Cbuild", (void *)w__Cbuild}, {"_FCbuild", (void *)w__FCbuild}, {"_LCbuild", (void *)w__LCbuild},
    {"_Cmulcc", (void *)w__Cmulcc}, {"_Cmulcr", (void *)w__Cmulcr}, {"_FCmulcc", (void *)w__FCmulcc},
    {"_FCmulcr", (void *)w__FCmulcr}, {"_LCmulcc", (void *)w__LCmulcc}, {"_LCmulcr", (void *)w__LCmulcr},
};

/* A Wine stub begins: sub $0x28,%rsp; lea ...(%rip),%rcx; lea ...(%rip),%rdx; call __wine_spec_unimplemented_stub */
static int is_wine_stub(const unsigned char *p)
{
    static const unsigned char head[] = {0x48, 0x83, 0xec, 0x28, 0x48, 0x8d, 0x0d};
    return memcmp(p, head, sizeof head) == 0 && p[11] == 0x48 && p[12] == 0x8d && p[13] == 0x15 && p[18] == 0xe8;
}

static int installed = -1;

static void install(void)
{
    if (GetProcAddress(GetModuleHandleA("ntdll.dll"), "wine_get_version") == NULL) return;
    HMODULE ucrt = LoadLibraryA("ucrtbase.dll");   /* kept loaded: it is the process's UCRT */
    installed = 0;
    if (ucrt == NULL) return;
    for (size_t i = 0; i < sizeof table / sizeof *table; ++i) {
        unsigned char *p = (unsigned char *)GetProcAddress(ucrt, table[i].name);
        if (p == NULL || !is_wine_stub(p)) continue;
        unsigned char jump[14] = {0xff, 0x25, 0, 0, 0, 0};   /* jmp *0(%rip); .quad target */
        void *target = table[i].impl;
        memcpy(jump + 6, &target, sizeof target);
        DWORD old;
        if (!VirtualProtect(p, sizeof jump, PAGE_EXECUTE_READWRITE, &old)) continue;
        memcpy(p, jump, sizeof jump);
        VirtualProtect(p, sizeof jump, old, &old);
        FlushInstructionCache(GetCurrentProcess(), p, sizeof jump);
        ++installed;
    }
}

__declspec(dllexport) int winecompat_installed(void) { return installed; }

BOOL WINAPI DllMain(HINSTANCE instance, DWORD reason, LPVOID reserved)
{
    (void)instance; (void)reserved;
    if (reason == DLL_PROCESS_ATTACH) install();
    return TRUE;
}
