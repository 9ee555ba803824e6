// Kernel development probe: compiles entry points of a SPIR-V module into compute pipelines and
// prints the driver's statistics of each (VK_KHR_pipeline_executable_properties: on the NVIDIA
// driver register count, binary size, local and shared memory), and writes whatever internal
// representations the driver offers into OUTDIR (the NVIDIA driver, 580, offers none).
// Every binding 0..23 of set 0 is declared a storage buffer (the kernels' only kind).
// Build: gcc -O1 -o pipeline_stats scripts/pipeline_stats.c -lvulkan   (libvulkan-dev)
// Usage: pipeline_stats host/kernels/kdray.spv OUTDIR trace::closest_bvh trace::any_bvh ...
#include <vulkan/vulkan.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CK(x) do { VkResult r_ = (x); if (r_ != VK_SUCCESS) { fprintf(stderr, "%s failed: %d\n", #x, r_); exit(1); } } while (0)

int main(int argc, char **argv) {
    if (argc < 4) { fprintf(stderr, "usage: pipeline_stats MODULE.spv OUTDIR ENTRY...\n"); return 2; }
    FILE *f = fopen(argv[1], "rb"); if (!f) { perror(argv[1]); return 1; }
    fseek(f, 0, SEEK_END); long n = ftell(f); fseek(f, 0, SEEK_SET);
    uint32_t *code = malloc(n); fread(code, 1, n, f); fclose(f);

    VkApplicationInfo app = { VK_STRUCTURE_TYPE_APPLICATION_INFO, 0, "pipeline_stats", 1, "none", 1, VK_API_VERSION_1_3 };
    VkInstanceCreateInfo ici = { VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO, 0, 0, &app };
    VkInstance inst; CK(vkCreateInstance(&ici, 0, &inst));
    uint32_t np = 8; VkPhysicalDevice pds[8]; CK(vkEnumeratePhysicalDevices(inst, &np, pds));
    VkPhysicalDevice pd = pds[0];
    VkPhysicalDeviceProperties props; vkGetPhysicalDeviceProperties(pd, &props);
    printf("device: %s\n", props.deviceName);

    VkPhysicalDevicePipelineExecutablePropertiesFeaturesKHR pef = { VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PIPELINE_EXECUTABLE_PROPERTIES_FEATURES_KHR };
    VkPhysicalDeviceVulkan13Features f13 = { VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES, &pef };
    VkPhysicalDeviceVulkan12Features f12 = { VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES, &f13 };
    VkPhysicalDeviceVulkan11Features f11 = { VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_1_FEATURES, &f12 };
    VkPhysicalDeviceFeatures2 feats = { VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2, &f11 };
    vkGetPhysicalDeviceFeatures2(pd, &feats);
    printf("pipelineExecutableInfo: %u\n", pef.pipelineExecutableInfo);

    uint32_t nq = 16; VkQueueFamilyProperties qf[16]; vkGetPhysicalDeviceQueueFamilyProperties(pd, &nq, qf);
    uint32_t qi = 0; for (uint32_t i = 0; i < nq; i++) if (qf[i].queueFlags & VK_QUEUE_COMPUTE_BIT) { qi = i; break; }
    float prio = 1.0f;
    VkDeviceQueueCreateInfo qci = { VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO, 0, 0, qi, 1, &prio };
    const char *exts[] = { "VK_KHR_pipeline_executable_properties" };
    VkDeviceCreateInfo dci = { VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO, &feats, 0, 1, &qci, 0, 0, 1, exts, 0 };
    VkDevice dev; CK(vkCreateDevice(pd, &dci, 0, &dev));
    PFN_vkGetPipelineExecutablePropertiesKHR gP = (void *)vkGetDeviceProcAddr(dev, "vkGetPipelineExecutablePropertiesKHR");
    PFN_vkGetPipelineExecutableStatisticsKHR gS = (void *)vkGetDeviceProcAddr(dev, "vkGetPipelineExecutableStatisticsKHR");
    PFN_vkGetPipelineExecutableInternalRepresentationsKHR gR = (void *)vkGetDeviceProcAddr(dev, "vkGetPipelineExecutableInternalRepresentationsKHR");

    VkShaderModuleCreateInfo smci = { VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO, 0, 0, (size_t)n, code };
    VkShaderModule sm; CK(vkCreateShaderModule(dev, &smci, 0, &sm));
    VkDescriptorSetLayoutBinding b[24];
    for (int i = 0; i < 24; i++) b[i] = (VkDescriptorSetLayoutBinding){ i, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_COMPUTE_BIT, 0 };
    VkDescriptorSetLayoutCreateInfo dl = { VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO, 0, 0, 24, b };
    VkDescriptorSetLayout dsl; CK(vkCreateDescriptorSetLayout(dev, &dl, 0, &dsl));
    VkPipelineLayoutCreateInfo pl = { VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO, 0, 0, 1, &dsl };
    VkPipelineLayout layout; CK(vkCreatePipelineLayout(dev, &pl, 0, &layout));

    for (int e = 3; e < argc; e++) {
        VkComputePipelineCreateInfo cp = { VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO, 0,
            VK_PIPELINE_CREATE_CAPTURE_STATISTICS_BIT_KHR | VK_PIPELINE_CREATE_CAPTURE_INTERNAL_REPRESENTATIONS_BIT_KHR,
            { VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO, 0, 0, VK_SHADER_STAGE_COMPUTE_BIT, sm, argv[e], 0 }, layout };
        VkPipeline pipe;
        VkResult r = vkCreateComputePipelines(dev, 0, 1, &cp, 0, &pipe);
        if (r != VK_SUCCESS) { printf("%s: pipeline failed %d\n", argv[e], r); continue; }
        VkPipelineInfoKHR pi = { VK_STRUCTURE_TYPE_PIPELINE_INFO_KHR, 0, pipe };
        uint32_t ne = 0; gP(dev, &pi, &ne, 0);
        VkPipelineExecutablePropertiesKHR ep[8]; for (int i = 0; i < 8; i++) ep[i] = (VkPipelineExecutablePropertiesKHR){ VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_PROPERTIES_KHR };
        if (ne > 8) ne = 8; gP(dev, &pi, &ne, ep);
        for (uint32_t x = 0; x < ne; x++) {
            printf("== %s [%s] subgroup %u\n", argv[e], ep[x].name, ep[x].subgroupSize);
            VkPipelineExecutableInfoKHR ei = { VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_INFO_KHR, 0, pipe, x };
            uint32_t ns = 0; gS(dev, &ei, &ns, 0);
            VkPipelineExecutableStatisticKHR *st = calloc(ns, sizeof *st);
            for (uint32_t i = 0; i < ns; i++) st[i].sType = VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_STATISTIC_KHR;
            gS(dev, &ei, &ns, st);
            for (uint32_t i = 0; i < ns; i++) {
                printf("  %-40s ", st[i].name);
                switch (st[i].format) {
                case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_BOOL32_KHR: printf("%u\n", st[i].value.b32); break;
                case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_INT64_KHR: printf("%lld\n", (long long)st[i].value.i64); break;
                case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_UINT64_KHR: printf("%llu\n", (unsigned long long)st[i].value.u64); break;
                default: printf("%g\n", st[i].value.f64);
                }
            }
            uint32_t nr = 0; gR(dev, &ei, &nr, 0);
            VkPipelineExecutableInternalRepresentationKHR *ir = calloc(nr, sizeof *ir);
            for (uint32_t i = 0; i < nr; i++) ir[i].sType = VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_INTERNAL_REPRESENTATION_KHR;
            gR(dev, &ei, &nr, ir);
            for (uint32_t i = 0; i < nr; i++) { ir[i].pData = malloc(ir[i].dataSize + 1); }
            gR(dev, &ei, &nr, ir);
            for (uint32_t i = 0; i < nr; i++) {
                printf("  IR %s (%s): %zu bytes, text %u\n", ir[i].name, ir[i].description, ir[i].dataSize, ir[i].isText);
                char path[512]; const char *base = strrchr(argv[e], ':'); base = base ? base + 1 : argv[e];
                snprintf(path, sizeof path, "%s/%s-%u-%u.txt", argv[2], base, x, i);
                FILE *o = fopen(path, "wb"); if (o) { fwrite(ir[i].pData, 1, ir[i].dataSize, o); fclose(o); }
            }
        }
        vkDestroyPipeline(dev, pipe, 0);
    }
    return 0;
}
