from setuptools import find_packages, setup

package_name = "ft_sim"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/launch", ["launch/demo.launch.py"]),
        ("share/" + package_name + "/config", ["config/ft_arms.rviz"]),
    ],
    install_requires=["setuptools"],
    extras_require={"test": ["pytest"]},  # colcon test runs test/ with pytest
    zip_safe=False,
    maintainer="ft-arms maintainers",
    maintainer_email="maintainers@ft-arms.org",
    description="Kinematic plant with failure injection, fault injector and end-to-end demo.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "demo = ft_sim.demo:main",
            "campaign = ft_sim.campaign:main",
            "sim_node = ft_sim.sim_node:main",
            "stack = ft_sim.stack:main",
            "fault_injector_node = ft_sim.fault_injector_node:main",
        ],
    },
)
