// Start-up for the host tests on QEMU's mps2-an386: the vector table (initial
// stack at the top of PSRAM, reset and fault handlers), the FPU switched on, then
// newlib's rdimon crt0 (_start: semihosting heap/stack info, .bss, constructors,
// main, exit through semihosting).
#include <stdint.h>

extern "C" {
void _start(void);
void _exit(int status);
extern uint32_t __stack;

__attribute__((naked, noreturn)) void Reset_Handler(void) {
  // CPACR: full access to CP10 and CP11 (the FPU) before any float instruction.
  __asm volatile(
      "ldr r0, =0xE000ED88\n"
      "ldr r1, [r0]\n"
      "orr r1, r1, #(0xF << 20)\n"
      "str r1, [r0]\n"
      "dsb\n"
      "isb\n"
      "b _start\n");
}

// A fault ends the run with a status the Makefile reports (no hang until timeout).
void Fault_Handler(void) { _exit(3); }

__attribute__((section(".isr_vector"), used)) void (*const g_vectors[16])(void) = {
    reinterpret_cast<void (*)(void)>(&__stack),
    Reset_Handler,
    Fault_Handler,  // NMI
    Fault_Handler,  // HardFault
    Fault_Handler,  // MemManage
    Fault_Handler,  // BusFault
    Fault_Handler,  // UsageFault
    nullptr, nullptr, nullptr, nullptr,
    Fault_Handler,  // SVC
    Fault_Handler,  // DebugMon
    nullptr,
    Fault_Handler,  // PendSV
    Fault_Handler,  // SysTick
};
}
