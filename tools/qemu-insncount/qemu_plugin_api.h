/*
 * The part of QEMU's TCG plugin API (API version 1, QEMU 7.x; also accepted by later
 * releases that keep a minimum version of 1) that insncount.c uses, declared from the
 * API's documented signatures. QEMU resolves these symbols in the plugin at load time.
 */
#ifndef M2_QEMU_PLUGIN_API_H
#define M2_QEMU_PLUGIN_API_H

#include <stddef.h>
#include <stdint.h>

#define M2_PLUGIN_EXPORT __attribute__((visibility("default")))

/* The API version this plugin is written against. */
#define M2_QEMU_PLUGIN_API_VERSION 1

/* Handle QEMU gives the plugin at install time. */
typedef uint64_t qemu_plugin_id_t;

/* Opaque to us: we read no field of the system information. */
typedef struct qemu_info_t qemu_info_t;

/* Opaque handles passed to the translation callback. */
struct qemu_plugin_tb;
struct qemu_plugin_insn;

/* What a callback may do with the guest registers (we touch none). */
enum qemu_plugin_cb_flags {
    QEMU_PLUGIN_CB_NO_REGS,
    QEMU_PLUGIN_CB_R_REGS,
    QEMU_PLUGIN_CB_RW_REGS,
};

/* Inline operations QEMU emits into translated code. */
enum qemu_plugin_op {
    QEMU_PLUGIN_INLINE_ADD_U64,
};

typedef void (*qemu_plugin_udata_cb_t)(qemu_plugin_id_t id, void *userdata);
typedef void (*qemu_plugin_vcpu_udata_cb_t)(unsigned int vcpu_index, void *userdata);
typedef void (*qemu_plugin_vcpu_tb_trans_cb_t)(qemu_plugin_id_t id,
                                               struct qemu_plugin_tb *tb);

/* Translation of every block. */
void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t id,
                                           qemu_plugin_vcpu_tb_trans_cb_t cb);
size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *tb);
struct qemu_plugin_insn *qemu_plugin_tb_get_insn(const struct qemu_plugin_tb *tb,
                                                 size_t idx);
uint64_t qemu_plugin_insn_vaddr(const struct qemu_plugin_insn *insn);

/* Execution of one instruction: a call, or an inline add to a 64-bit counter. */
void qemu_plugin_register_vcpu_insn_exec_cb(struct qemu_plugin_insn *insn,
                                            qemu_plugin_vcpu_udata_cb_t cb,
                                            enum qemu_plugin_cb_flags flags,
                                            void *userdata);
void qemu_plugin_register_vcpu_insn_exec_inline(struct qemu_plugin_insn *insn,
                                                enum qemu_plugin_op op, void *ptr,
                                                uint64_t imm);

/* End of the run, and output to QEMU's log (shown with `-d plugin`). */
void qemu_plugin_register_atexit_cb(qemu_plugin_id_t id, qemu_plugin_udata_cb_t cb,
                                    void *userdata);
void qemu_plugin_outs(const char *string);

#endif
