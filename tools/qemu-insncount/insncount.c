/*
 * m2ctl's instruction counter: a QEMU TCG plugin that counts, exactly, the guest
 * instructions executed between two marker functions of a firmware image.
 *
 * Arguments (QEMU `-plugin libinsncount.so,start=<addr>,end=<addr>`): the entry
 * addresses of `bench_start` and `bench_end` (hex with 0x, or decimal; the Thumb bit
 * is ignored). Every instruction adds one to a counter (an inline add QEMU emits into
 * the translated code, so the count stays exact when a block is left early). A
 * section opens when `bench_start`'s first instruction executes and closes when
 * `bench_end`'s first instruction executes; it then prints
 *     BENCH n=<k> insns=<count>
 * (k = 1, 2, ... in order) and, when QEMU exits,
 *     TOTAL insns=<all instructions executed>
 * through QEMU's log (`-d plugin`, `-D <file>`). The count of a section is the
 * instructions from `bench_start`'s entry up to, not including, `bench_end`'s entry:
 * an empty pair counts the marker call and return. Counts, not cycles: QEMU has no
 * timing model.
 *
 * Single vCPU (Cortex-M): the counter is a plain global.
 */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "qemu_plugin_api.h"

M2_PLUGIN_EXPORT int qemu_plugin_version = M2_QEMU_PLUGIN_API_VERSION;

/* Thumb code addresses carry bit 0 in symbols and branches, never in the PC. */
#define THUMB_BIT ((uint64_t)1)

/* Instructions executed since QEMU started (incremented by translated code). */
static uint64_t executed;
/* Marker entry addresses (Thumb bit cleared). */
static uint64_t start_addr;
static uint64_t end_addr;
/* Value of `executed` when the open section began, and whether one is open. */
static uint64_t section_base;
static int section_open;
/* Sections closed so far. */
static unsigned sections;

/* Distinguishes the two marker callbacks through their user data. */
static int start_tag;
static int end_tag;

static void on_marker(unsigned int vcpu_index, void *userdata)
{
    char line[80];
    (void)vcpu_index;
    if (userdata == &start_tag) {
        section_base = executed;
        section_open = 1;
    } else if (section_open) {
        sections++;
        snprintf(line, sizeof line, "BENCH n=%u insns=%" PRIu64 "\n", sections,
                 executed - section_base);
        qemu_plugin_outs(line);
        section_open = 0;
    }
}

static void on_translate(qemu_plugin_id_t id, struct qemu_plugin_tb *tb)
{
    size_t n = qemu_plugin_tb_n_insns(tb);
    (void)id;
    for (size_t i = 0; i < n; i++) {
        struct qemu_plugin_insn *insn = qemu_plugin_tb_get_insn(tb, i);
        uint64_t pc = qemu_plugin_insn_vaddr(insn) & ~THUMB_BIT;
        /* The marker callback sees the counter consistently before (or after) this
         * instruction's own add, for both markers alike, so the difference is the
         * same either way. */
        if (pc == start_addr) {
            qemu_plugin_register_vcpu_insn_exec_cb(insn, on_marker, QEMU_PLUGIN_CB_NO_REGS,
                                                   &start_tag);
        } else if (pc == end_addr) {
            qemu_plugin_register_vcpu_insn_exec_cb(insn, on_marker, QEMU_PLUGIN_CB_NO_REGS,
                                                   &end_tag);
        }
        qemu_plugin_register_vcpu_insn_exec_inline(insn, QEMU_PLUGIN_INLINE_ADD_U64,
                                                   &executed, 1);
    }
}

static void on_qemu_exit(qemu_plugin_id_t id, void *userdata)
{
    char line[64];
    (void)id;
    (void)userdata;
    snprintf(line, sizeof line, "TOTAL insns=%" PRIu64 "\n", executed);
    qemu_plugin_outs(line);
}

/* Parses "key=<number>"; returns 1 and stores the value when `arg` is that key. */
static int parse_addr(const char *arg, const char *key, uint64_t *out)
{
    size_t k = strlen(key);
    char *end = NULL;
    unsigned long long v;
    if (strncmp(arg, key, k) != 0 || arg[k] != '=') {
        return 0;
    }
    v = strtoull(arg + k + 1, &end, 0);
    if (end == arg + k + 1 || *end != '\0') {
        return -1;
    }
    *out = (uint64_t)v & ~THUMB_BIT;
    return 1;
}

M2_PLUGIN_EXPORT int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info,
                                         int argc, char **argv)
{
    int have_start = 0;
    int have_end = 0;
    (void)info;
    for (int i = 0; i < argc; i++) {
        int s = parse_addr(argv[i], "start", &start_addr);
        int e = s ? 0 : parse_addr(argv[i], "end", &end_addr);
        if (s < 0 || e < 0 || (s == 0 && e == 0)) {
            fprintf(stderr, "insncount: bad argument '%s' (want start=<addr>,end=<addr>)\n",
                    argv[i]);
            return -1;
        }
        have_start |= s;
        have_end |= e;
    }
    if (!have_start || !have_end || start_addr == end_addr) {
        fprintf(stderr, "insncount: need distinct start=<addr> and end=<addr>\n");
        return -1;
    }
    qemu_plugin_register_vcpu_tb_trans_cb(id, on_translate);
    qemu_plugin_register_atexit_cb(id, on_qemu_exit, NULL);
    return 0;
}
