/*
 * insncount: a QEMU TCG plugin (API v1) that counts the guest instructions executed
 * between two marker functions, and attributes them to the functions they belong to.
 *
 *   -plugin ./libinsncount.so,arg=start=0xADDR,arg=stop=0xADDR,
 *           arg=on=0xADDR,arg=off=0xADDR,arg=syms=FILE,arg=out=FILE
 *
 * start / stop: first instructions of bench_start / bench_stop. Every instruction
 *   executed from `start` (inclusive) to `stop` (exclusive) is counted; at `stop` the
 *   count is written as "count <n>" (one line per region, in order).
 * on / off: first instructions of bench_profile_on / bench_profile_off. Between them the
 *   counted instructions are also attributed to functions (from `syms`: lines
 *   "ADDR SIZE NAME", hex ADDR and SIZE, e.g. from `nm -S`); at exit the profile is
 *   written as "func <n> <name>" lines. Instructions of helper functions (memcpy/memset,
 *   compiler-builtins soft-float, libm) are also attributed to the function that called
 *   the helper: "call <n> <helper> <- <caller>" lines.
 * out: the file to write to (default: stderr through qemu_plugin_outs).
 *
 * Deterministic: the count depends only on the guest code and its inputs.
 */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "qemu_plugin_api.h"

QEMU_PLUGIN_EXPORT int qemu_plugin_version = 1;

#define MARK_START 1u
#define MARK_STOP 2u
#define MARK_ON 4u
#define MARK_OFF 8u
#define MARK_ENTRY 16u
#define FLAG_BITS 5u
#define MAX_DEPTH 256

struct sym {
    uint64_t addr, size;
    char *name;
    uint64_t count;
    uint64_t incl; /* inclusive: its own and its callees' instructions */
    uint32_t on_stack;
    int helper;
};

static uint64_t a_start, a_stop, a_on, a_off;
static struct sym *syms;
static size_t nsyms;
static FILE *out;

static int active, profiling;
static uint64_t count;
static uint64_t unattributed;
static uint64_t *pairs; /* pairs[helper * nsyms + caller] */
static uint64_t prev_sym, caller;
/* The shadow call stack of the profile (symbol index + 1, and whether the entry is the
 * lowest occurrence of that function), for the inclusive counts: a call is an instruction
 * at a function's first address; reaching a function lower on the stack is a return. */
static uint64_t stack_sym[MAX_DEPTH];
static int stack_first[MAX_DEPTH];
static int depth;

static void stack_push(uint64_t s)
{
    if (depth == MAX_DEPTH) {
        return;
    }
    stack_sym[depth] = s;
    stack_first[depth] = syms[s - 1].on_stack++ == 0;
    depth++;
}

static void stack_pop(void)
{
    depth--;
    syms[stack_sym[depth] - 1].on_stack--;
}

static void stack_reset(void)
{
    while (depth > 0) {
        stack_pop();
    }
}

static void track(uint64_t s, int entry)
{
    if (entry || depth == 0) {
        stack_push(s);
    } else if (stack_sym[depth - 1] != s) {
        if (syms[s - 1].on_stack) {
            while (stack_sym[depth - 1] != s) {
                stack_pop();
            }
        } else {
            stack_push(s);
        }
    }
    for (int i = 0; i < depth; i++) {
        if (stack_first[i]) {
            syms[stack_sym[i] - 1].incl++;
        }
    }
}

static int is_helper(const char *n)
{
    static const char *const pat[] = {"memcpy", "memset", "memclr", "memmove",
                                      "__aeabi_", "compiler_builtins::", "libm::",
                                      "fmaxf", "fminf", NULL};
    for (int i = 0; pat[i]; i++) {
        if (strstr(n, pat[i])) {
            return 1;
        }
    }
    return 0;
}

static void emit(const char *s)
{
    if (out) {
        fputs(s, out);
        fflush(out);
    } else {
        qemu_plugin_outs(s);
    }
}

static int cmp_sym(const void *a, const void *b)
{
    const struct sym *x = a, *y = b;
    return x->addr < y->addr ? -1 : x->addr > y->addr;
}

static void load_syms(const char *path)
{
    FILE *f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "insncount: cannot open %s\n", path);
        return;
    }
    size_t cap = 1024;
    syms = calloc(cap, sizeof *syms);
    char line[4096];
    while (fgets(line, sizeof line, f)) {
        uint64_t addr, size;
        int n = 0;
        if (sscanf(line, "%" SCNx64 " %" SCNx64 " %n", &addr, &size, &n) < 2 || n == 0) {
            continue;
        }
        char *name = line + n;
        name[strcspn(name, "\n")] = 0;
        if (nsyms == cap) {
            cap *= 2;
            syms = realloc(syms, cap * sizeof *syms);
        }
        syms[nsyms].addr = addr & ~(uint64_t)1; /* Thumb bit */
        syms[nsyms].size = size;
        syms[nsyms].name = strdup(name);
        syms[nsyms].count = 0;
        nsyms++;
    }
    fclose(f);
    qsort(syms, nsyms, sizeof *syms, cmp_sym);
    for (size_t i = 0; i < nsyms; i++) {
        syms[i].helper = is_helper(syms[i].name);
    }
    pairs = calloc(nsyms * nsyms + 1, sizeof *pairs);
}

/* Index + 1 of the function containing addr, or 0. */
static uint64_t find_sym(uint64_t addr)
{
    size_t lo = 0, hi = nsyms;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        if (syms[mid].addr <= addr) {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    if (lo == 0) {
        return 0;
    }
    struct sym *s = &syms[lo - 1];
    return addr < s->addr + (s->size ? s->size : 1) ? lo : 0;
}

static void on_insn(unsigned int vcpu, void *udata)
{
    uintptr_t u = (uintptr_t)udata;
    (void)vcpu;
    if (u & (MARK_START | MARK_STOP | MARK_ON | MARK_OFF)) {
        if (u & MARK_STOP) {
            if (active) {
                char buf[64];
                snprintf(buf, sizeof buf, "count %" PRIu64 "\n", count);
                emit(buf);
            }
            active = 0;
        }
        if (u & MARK_START) {
            active = 1;
            count = 0;
        }
        if (u & MARK_ON) {
            profiling = 1;
            stack_reset();
        }
        if (u & MARK_OFF) {
            profiling = 0;
        }
    }
    if (active) {
        count++;
        if (profiling) {
            uint64_t s = u >> FLAG_BITS;
            if (s) {
                struct sym *f = &syms[s - 1];
                f->count++;
                track(s, (u & MARK_ENTRY) != 0);
                if (f->helper) {
                    if (prev_sym && !syms[prev_sym - 1].helper) {
                        caller = prev_sym;
                    }
                    if (caller) {
                        pairs[(s - 1) * nsyms + (caller - 1)]++;
                    }
                } else {
                    caller = 0;
                }
            } else {
                unattributed++;
            }
            prev_sym = s;
        }
    }
}

static void on_tb_trans(qemu_plugin_id_t id, struct qemu_plugin_tb *tb)
{
    (void)id;
    size_t n = qemu_plugin_tb_n_insns(tb);
    for (size_t i = 0; i < n; i++) {
        struct qemu_plugin_insn *insn = qemu_plugin_tb_get_insn(tb, i);
        uint64_t pc = qemu_plugin_insn_vaddr(insn);
        uint64_t s = find_sym(pc);
        uintptr_t u = (uintptr_t)s << FLAG_BITS;
        if (s && syms[s - 1].addr == pc) u |= MARK_ENTRY;
        if (pc == a_start) u |= MARK_START;
        if (pc == a_stop) u |= MARK_STOP;
        if (pc == a_on) u |= MARK_ON;
        if (pc == a_off) u |= MARK_OFF;
        qemu_plugin_register_vcpu_insn_exec_cb(insn, on_insn, QEMU_PLUGIN_CB_NO_REGS,
                                               (void *)u);
    }
}

static int cmp_count(const void *a, const void *b)
{
    const struct sym *x = a, *y = b;
    return x->count > y->count ? -1 : x->count < y->count;
}

static void plugin_exit(qemu_plugin_id_t id, void *p)
{
    (void)id;
    (void)p;
    char buf[8400];
    for (size_t h = 0; pairs && h < nsyms; h++) {
        for (size_t c = 0; c < nsyms; c++) {
            uint64_t n = pairs[h * nsyms + c];
            if (n) {
                snprintf(buf, sizeof buf, "call %" PRIu64 " %s <- %s\n", n, syms[h].name,
                         syms[c].name);
                emit(buf);
            }
        }
    }
    qsort(syms, nsyms, sizeof *syms, cmp_count);
    for (size_t i = 0; i < nsyms && syms[i].count; i++) {
        snprintf(buf, sizeof buf, "func %" PRIu64 " %s\n", syms[i].count, syms[i].name);
        emit(buf);
    }
    for (size_t i = 0; i < nsyms; i++) {
        if (syms[i].incl) {
            snprintf(buf, sizeof buf, "incl %" PRIu64 " %s\n", syms[i].incl, syms[i].name);
            emit(buf);
        }
    }
    if (unattributed) {
        snprintf(buf, sizeof buf, "func %" PRIu64 " (no symbol)\n", unattributed);
        emit(buf);
    }
    if (out) {
        fclose(out);
        out = NULL;
    }
}

QEMU_PLUGIN_EXPORT int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info,
                                           int argc, char **argv)
{
    (void)info;
    for (int i = 0; i < argc; i++) {
        char *eq = strchr(argv[i], '=');
        if (!eq) {
            continue;
        }
        *eq = 0;
        const char *k = argv[i], *v = eq + 1;
        if (!strcmp(k, "start")) a_start = strtoull(v, NULL, 0) & ~1ull;
        else if (!strcmp(k, "stop")) a_stop = strtoull(v, NULL, 0) & ~1ull;
        else if (!strcmp(k, "on")) a_on = strtoull(v, NULL, 0) & ~1ull;
        else if (!strcmp(k, "off")) a_off = strtoull(v, NULL, 0) & ~1ull;
        else if (!strcmp(k, "syms")) load_syms(v);
        else if (!strcmp(k, "out")) out = fopen(v, "w");
    }
    if (!a_start || !a_stop) {
        fprintf(stderr, "insncount: start= and stop= addresses are required\n");
        return -1;
    }
    qemu_plugin_register_vcpu_tb_trans_cb(id, on_tb_trans);
    qemu_plugin_register_atexit_cb(id, plugin_exit, NULL);
    return 0;
}
